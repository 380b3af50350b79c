"""Training on several processes (``torchrun``, DDP): two CPU processes with the gloo
backend follow the loss curve of one process on the same global batch: the
generative stage and the motion stage."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import torch

RUN = """
import sys
import torch
import torch.distributed as dist
from loosefit.model.generative import GenerativeConfig
from loosefit.train.generative import TrainGenerativeConfig, train_generative
rank, world = int(sys.argv[1]), int(sys.argv[2])
init, data, out = sys.argv[3:6]
torch.set_num_threads(1)  # two processes on a small CPU: no oversubscription
if world > 1:
    dist.init_process_group("gloo", init_method=init, rank=rank, world_size=world)
cfg = TrainGenerativeConfig(model=GenerativeConfig(uv_size=32, channels=(4, 8, 8, 8),
                            rec_hidden=(16, 16, 16)), epochs=4, batch_size=7, lr=2e-3,
                            eval_every=1000, checkpoint_every=2)
train_generative(data, out, cfg, log=lambda *_: None, progress=False)
if world > 1:
    dist.destroy_process_group()
"""


@pytest.mark.heavy
def test_two_processes_follow_one_process_s_loss_curve(toy_dataset, tmp_path):
    one, two = tmp_path / "one", tmp_path / "two"
    init = f"file://{tmp_path / 'rendezvous'}"
    single = subprocess.run(
        [sys.executable, "-c", RUN, "0", "1", init, str(toy_dataset), str(one)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert single.returncode == 0, single.stderr[-3000:]
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", RUN, str(r), "2", init, str(toy_dataset), str(two)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for r in range(2)
    ]
    for p in procs:
        _, err = p.communicate(timeout=600)
        assert p.returncode == 0, err[-3000:]
    a = torch.load(one / "checkpoint.pt", weights_only=False)
    b = torch.load(two / "checkpoint.pt", weights_only=False)
    # batches of 7 over 2 processes (4 + 3 items, and a last batch of 1: one process idle)
    for ha, hb in zip(a["history"], b["history"], strict=True):
        for k in ha:
            np.testing.assert_allclose(hb[k], ha[k], rtol=1e-4, atol=1e-6, err_msg=k)
    # the same model: the same garments out (weights a norm layer cancels, such as a conv's
    # bias before InstanceNorm, get only rounding noise for gradient, which Adam turns into
    # steps: they may differ and change nothing)
    from loosefit.data.format import DatasetReader
    from loosefit.inference.checkpoints import load_generative
    from loosefit.model.motion_features import garment_in_root_frame

    seq = DatasetReader(toy_dataset).read("c")
    x = garment_in_root_frame(seq.motion, seq.garment_vertices)
    ga, _ = load_generative(one / "checkpoint.pt")
    gb, _ = load_generative(two / "checkpoint.pt")
    with torch.no_grad():
        torch.testing.assert_close(
            gb.reconstruct_all(x, 8), ga.reconstruct_all(x, 8), rtol=1e-3, atol=1e-4
        )
    assert (two / "report.json").is_file()  # written once, by the first process


RUN_MOTION = """
import sys
import numpy as np
import torch
import torch.distributed as dist
from loosefit.model.motion_encoder import MotionEncoderConfig
from loosefit.inference.timeline import RolloutConfig
from loosefit.train.motion import TrainMotionConfig, train_motion
rank, world = int(sys.argv[1]), int(sys.argv[2])
init, data, generative, rest, out = sys.argv[3:8]
torch.set_num_threads(1)  # two processes on a small CPU: no oversubscription
if world > 1:
    dist.init_process_group("gloo", init_method=init, rank=rank, world_size=world)
cfg = TrainMotionConfig(model=MotionEncoderConfig(motion_fc=16, gru=24),
                        rollout=RolloutConfig(warm_frames=2, blend_seconds=0.1), epochs=4,
                        batch_size=3, window=6, lr=3e-3, mirror=True, previous_noise=0.01,
                        teacher_fraction=1.0, checkpoint_every=2, eval_every=1000)
train_motion(data, generative, out, cfg, log=lambda *_: None, progress=False,
             rest_state=torch.from_numpy(np.load(rest)))
if world > 1:
    dist.destroy_process_group()
"""


@pytest.mark.heavy
def test_two_processes_train_the_motion_stage_as_one(toy_dataset, generative, skirt, tmp_path):
    one, two = tmp_path / "one", tmp_path / "two"
    init = f"file://{tmp_path / 'rendezvous'}"
    rest = tmp_path / "rest.npy"
    np.save(rest, skirt.vertices.astype(np.float32))
    common = [init, str(toy_dataset), str(generative), str(rest)]
    single = subprocess.run(
        [sys.executable, "-c", RUN_MOTION, "0", "1", *common, str(one)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert single.returncode == 0, single.stderr[-3000:]
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", RUN_MOTION, str(r), "2", *common, str(two)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for r in range(2)
    ]
    for p in procs:
        _, err = p.communicate(timeout=600)
        assert p.returncode == 0, err[-3000:]
    a = torch.load(one / "checkpoint.pt", weights_only=False)
    b = torch.load(two / "checkpoint.pt", weights_only=False)
    # 4 clips (2 and their mirrors) in batches of 3 (2 + 1 clips on the two processes) and
    # 1 (one process idle); teacher choices and noise drawn for the whole batch
    assert len(a["history"]) == 4 and 0 < a["history"][1]["teacher"] < 1
    for ha, hb in zip(a["history"], b["history"], strict=True):
        for k in ha:
            np.testing.assert_allclose(hb[k], ha[k], rtol=1e-4, atol=1e-6, err_msg=k)
    # the same encoder (but a convolution's bias before InstanceNorm, which the norm cancels:
    # rounding noise for gradient, which Adam turns into steps)
    cancelled = {f"state_encoder.convs.{i}.0.bias" for i in range(4)}
    for k, w in a["model"].items():
        if k not in cancelled:
            torch.testing.assert_close(b["model"][k], w, rtol=1e-4, atol=2e-5, msg=k)
    assert (two / "report.json").is_file() and (two / "model.pt").is_file()  # the first's


@pytest.mark.heavy
def test_torchrun_trains_the_motion_stage_once_reported(toy_dataset, generative, skirt, tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    np.save(run / "rest_state.npy", skirt.vertices.astype(np.float32))  # no cloth to settle
    cmd = [
        sys.executable,
        "-m",
        "torch.distributed.run",
        "--standalone",
        "--nproc-per-node",
        "2",
        "-m",
        "loosefit.cli",
        "train",
        "motion",
        "--data",
        str(toy_dataset),
        "--generative",
        str(generative),
        "--preset",
        "cpu",
        "--epochs",
        "1",
        "--max-frames",
        "8",
        "--threads",
        "1",
        "--out",
        str(run),
    ]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.count("# Dynamic motion encoder") == 1  # the report, once
    assert (run / "model.pt").is_file() and (run / "report.json").is_file()


def test_torchrun_refuses_the_detail_and_baseline_stages(toy_dataset, tmp_path):
    import os

    env = {**os.environ, "WORLD_SIZE": "2", "RANK": "0", "LOCAL_RANK": "0"}
    own = {"detail": ["--motion", "x.pt"], "baseline": ["--method", "santesteban"]}
    for stage in ("detail", "baseline"):
        run = subprocess.run(
            [
                sys.executable,
                "-m",
                "loosefit.cli",
                "train",
                stage,
                "--data",
                str(toy_dataset),
                *own[stage],
                "--out",
                str(tmp_path / stage),
            ],
            capture_output=True,
            text=True,
            env=env,
            timeout=300,
        )
        assert run.returncode == 2 and "torchrun" in run.stderr, run.stderr[-2000:]
        assert "generative or motion" in run.stderr
        assert not (tmp_path / stage).exists()
