"""Long runs killed with SIGKILL and run again: the result is the uninterrupted run's, bit
for bit; nothing finished is done again; no half-written file is taken for a whole one.

Each run is a subprocess (what a user's terminal or a cluster does); it is killed the moment
its first checkpoint (or finished clip) appears on disk, at a random point of the next
epoch's (clip's) work, then the same command runs again to the end.
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch

pytestmark = pytest.mark.heavy  # long runs in subprocesses, killed and run again

TRAIN_GENERATIVE = """
import sys
from loosefit.model.generative import GenerativeConfig
from loosefit.train.generative import TrainGenerativeConfig, train_generative
cfg = TrainGenerativeConfig(model=GenerativeConfig(uv_size=32, channels=(4, 8, 8, 8),
                            rec_hidden=(16, 16, 16)), epochs=8, batch_size=8, lr=2e-3,
                            eval_every=1000, checkpoint_every=1)
train_generative(sys.argv[1], sys.argv[2], cfg, log=print, progress=False)
"""

TRAIN_MOTION = """
import sys
import torch
from loosefit.model.motion_encoder import MotionEncoderConfig
from loosefit.inference.timeline import RolloutConfig
from loosefit.train.motion import TrainMotionConfig, train_motion
cfg = TrainMotionConfig(model=MotionEncoderConfig(motion_fc=16, gru=24),
                        rollout=RolloutConfig(warm_frames=2, blend_seconds=0.1), epochs=8,
                        batch_size=2, window=6, lr=3e-3, checkpoint_every=1, eval_every=1000)
from loosefit.data.format import DatasetReader
rest = torch.from_numpy(DatasetReader(sys.argv[1]).template.vertices)
train_motion(sys.argv[1], sys.argv[3], sys.argv[2], cfg, log=print, progress=False,
             rest_state=rest)
"""


TRAIN_DETAIL = """
import sys
from loosefit.model.detail import DetailConfig
from loosefit.train.detail import TrainDetailConfig, train_detail
cfg = TrainDetailConfig(model=DetailConfig(disc_channels=(4, 8, 8), patches=(32, 16)),
                        epochs=8, batch_size=4, lr=3e-3, checkpoint_every=1)
train_detail(sys.argv[1], sys.argv[3], sys.argv[2], cfg, log=print, progress=False)
"""


def _run(code: str, *args) -> subprocess.CompletedProcess:
    run = subprocess.run(
        [sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True, timeout=600
    )
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-3000:]
    return run


def _kill_when(code: str, args: list, appears: Path, seed: int) -> None:
    """Start the run, SIGKILL it a random moment after ``appears`` exists, and before the file
    is written again three times (a toy run's epochs can be shorter than the random wait: it
    must still be killed before its end)."""
    proc = subprocess.Popen(
        [sys.executable, "-c", code, *map(str, args)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 300
        while not appears.exists():
            assert proc.poll() is None, "the run ended before it could be killed"
            assert time.monotonic() < deadline, "nothing appeared to kill the run after"
            time.sleep(0.02)
        end = time.monotonic() + random.Random(seed).uniform(0.0, 0.3)
        last, rewrites = appears.stat().st_mtime_ns, 0
        while time.monotonic() < end and rewrites < 3:
            time.sleep(0.002)
            written = appears.stat().st_mtime_ns  # replaced atomically: always there
            rewrites, last = rewrites + (written != last), written
        assert proc.poll() is None, "the run ended before it could be killed"
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait()


def _weights(path: Path) -> dict:
    return torch.load(path, weights_only=False)["model"]


@pytest.fixture(scope="module")
def motion_stage(toy_dataset, generative, tmp_path_factory):
    """A motion stage trained uninterrupted (its model.pt): the run a killed motion stage must
    match, and the motion stage the detail stage trains on."""
    out = tmp_path_factory.mktemp("motion")
    _run(TRAIN_MOTION, toy_dataset, out, generative)
    return out / "model.pt"


@pytest.mark.parametrize("stage", ["generative", "motion", "detail"])
def test_a_killed_training_resumes_to_the_same_weights(
    stage, toy_dataset, generative, tmp_path, request
):
    code = {"generative": TRAIN_GENERATIVE, "motion": TRAIN_MOTION, "detail": TRAIN_DETAIL}[stage]
    extra = {
        "generative": [],
        "motion": [generative],
        "detail": [request.getfixturevalue("motion_stage")] if stage == "detail" else [],
    }[stage]
    killed = tmp_path / "killed"
    if stage == "motion":  # the uninterrupted run: the detail stage's motion stage is that run
        whole = request.getfixturevalue("motion_stage").parent
    else:
        whole = tmp_path / "whole"
        _run(code, toy_dataset, whole, *extra)
    _kill_when(code, [toy_dataset, killed, *extra], killed / "checkpoint.pt", seed=len(stage))
    mid = torch.load(killed / "checkpoint.pt", weights_only=False)
    assert 1 <= mid["epoch"] < 8, "killed after the first checkpoint, before the end"
    assert not (killed / "report.json").exists()  # an unfinished run reports nothing
    log = _run(code, toy_dataset, killed, *extra).stdout
    assert f"resumed {killed / 'checkpoint.pt'} at epoch {mid['epoch']}" in log
    # the result is the uninterrupted run's, bit for bit
    a, b = _weights(whole / "checkpoint.pt"), _weights(killed / "checkpoint.pt")
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    history = torch.load(killed / "checkpoint.pt", weights_only=False)["history"]
    assert [h["epoch"] for h in history] == list(range(1, 9))  # no epoch done twice
    assert (killed / "report.json").is_file()
    assert not [p.name for p in killed.iterdir() if "partial" in p.name]  # none left over


SIMULATE = """
import sys
from loosefit.sim.generate import generate
from loosefit.sim.presets import preset
generate(preset("tiny"), sys.argv[1], workers=1, progress=False)
"""


def test_a_killed_simulation_resumes_without_redoing_a_clip(tiny_simulated, tmp_path):
    import json

    import numpy as np

    from loosefit.data.format import DatasetReader

    whole, killed = tiny_simulated, tmp_path / "killed"  # whole: the uninterrupted run
    first = killed / "sequences" / "kick_000.npz"
    _kill_when(SIMULATE, [killed], first, seed=3)
    manifest = json.loads((killed / "manifest.json").read_text())
    assert not manifest["complete"]
    done_at = first.stat().st_mtime_ns
    _run(SIMULATE, killed)
    assert first.stat().st_mtime_ns == done_at  # the finished clip was not simulated again
    a, b = DatasetReader(whole), DatasetReader(killed)
    assert a.split("all") == b.split("all")
    for name in a.split("all"):
        assert np.array_equal(a.read(name).garment_vertices, b.read(name).garment_vertices)
    assert not [p for p in killed.rglob("*") if "partial" in p.name]
