"""Training on several processes (``torchrun``, DDP): two CPU processes with the gloo
backend follow the loss curve of one process on the same global batch (issue 25, item 3)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import torch

RUN = """
import sys
import torch.distributed as dist
from loosefit.model.generative import GenerativeConfig
from loosefit.train.generative import TrainGenerativeConfig, train_generative
rank, world = int(sys.argv[1]), int(sys.argv[2])
init, data, out = sys.argv[3:6]
if world > 1:
    dist.init_process_group("gloo", init_method=init, rank=rank, world_size=world)
cfg = TrainGenerativeConfig(model=GenerativeConfig(uv_size=32, channels=(4, 8, 8, 8),
                            rec_hidden=(16, 16, 16)), epochs=4, batch_size=7, lr=2e-3,
                            eval_every=1000, checkpoint_every=2)
train_generative(data, out, cfg, log=lambda *_: None, progress=False)
if world > 1:
    dist.destroy_process_group()
"""


def test_two_processes_follow_one_process_s_loss_curve(toy_dataset, tmp_path):
    one, two = tmp_path / "one", tmp_path / "two"
    init = f"file://{tmp_path / 'rendezvous'}"
    single = subprocess.run([sys.executable, "-c", RUN, "0", "1", init, str(toy_dataset),
                             str(one)], capture_output=True, text=True, timeout=600)  # fmt: skip
    assert single.returncode == 0, single.stderr[-3000:]
    procs = [subprocess.Popen([sys.executable, "-c", RUN, str(r), "2", init, str(toy_dataset),
                               str(two)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True) for r in range(2)]  # fmt: skip
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
        torch.testing.assert_close(gb.reconstruct_all(x, 8), ga.reconstruct_all(x, 8),
                                   rtol=1e-3, atol=1e-4)  # fmt: skip
    assert (two / "report.json").is_file()  # written once, by the first process


def test_torchrun_trains_the_generative_stage_and_refuses_the_others(toy_dataset, tmp_path):
    import os

    env = {**os.environ, "WORLD_SIZE": "2", "RANK": "0", "LOCAL_RANK": "0"}
    run = subprocess.run([sys.executable, "-m", "loosefit.cli", "train", "motion", "--data",
                          str(toy_dataset), "--generative", "x.pt", "--out", str(tmp_path / "m")],
                         capture_output=True, text=True, env=env, timeout=300)  # fmt: skip
    assert run.returncode == 2 and "torchrun" in run.stderr and "generative" in run.stderr
    assert not (tmp_path / "m").exists()
