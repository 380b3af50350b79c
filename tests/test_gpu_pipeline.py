"""scripts/gpu_pipeline.py at toy size on the CPU: every step, a budget that runs out, resume."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

# the GPU pipeline's scripts at toy size: simulations and training in subprocesses
pytestmark = pytest.mark.heavy

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "gpu_pipeline.py"


def pipeline(work: Path, out: Path, budget: float) -> subprocess.CompletedProcess:
    cmd = [
        sys.executable,
        str(SCRIPT),
        "run",
        "--tiny",
        "--device",
        "cpu",
        "--work",
        str(work),
        "--out",
        str(out),
        "--budget",
        str(budget),
    ]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=900)


def test_the_pipeline_runs_in_budgeted_calls_and_brings_back_the_model(tmp_path):
    work, out = tmp_path / "work", tmp_path / "out"
    # A call too short for the whole pipeline stops (inside a step or before the next one)
    # and says to call again, having brought back what there is. No figure of speed: the
    # calls go on until the pipeline is done, however fast this machine is.
    first = pipeline(work, out, 25)
    assert first.returncode == 3, first.stdout + first.stderr
    assert "call again" in first.stdout
    assert (out / "logs.txt").is_file()
    for _ in range(12):  # each call resumes where the last stopped
        simulated = (work / "simulate.done").is_file()
        call = pipeline(work, out, 300)
        assert call.returncode in (0, 3), call.stdout + call.stderr
        if simulated:  # a finished step is never run again
            assert "simulate (" not in call.stdout
        if call.returncode == 0:
            break
        assert "call again" in call.stdout
    assert call.returncode == 0 and call.stdout.strip().endswith("done"), call.stdout
    for name in (
        "manifest.json",
        "model/generative.pt",
        "model/motion.pt",
        "table1.md",
        "table3.md",
        "generative_report.md",
        "motion_report.md",
        "BATCH_INFERENCE.md",
    ):
        path = out / name
        assert path.is_file() and path.stat().st_size < 16 * 2**20, name
    assert "spin_001" in (out / "table1.md").read_text()
    # Everything done: a third call does nothing.
    third = pipeline(work, out, 60)
    assert third.returncode == 0 and "] " not in third.stdout


def test_the_dance_pipeline_trains_every_stage_and_brings_back_the_set(tmp_path, toy_dataset):
    """The dance set on a GPU (``--preset dance``), at toy size: the data comes from the toy
    set (simulating is the step the paper pipeline's test runs), then the three stages, the
    package with its detail stage and both tables."""
    import shutil

    work, out = tmp_path / "work", tmp_path / "out"
    shutil.copytree(toy_dataset, work / "data")
    (work / "simulate.done").write_text("{}")
    cmd = [
        sys.executable,
        str(SCRIPT),
        "run",
        "--preset",
        "dance",
        "--tiny",
        "--device",
        "cpu",
        "--work",
        str(work),
        "--out",
        str(out),
        "--budget",
        "600",
    ]
    call = subprocess.run(cmd, capture_output=True, text=True, timeout=900)
    assert call.returncode == 0 and call.stdout.strip().endswith("done"), call.stdout
    for step in ("generative", "motion", "detail", "package", "table1", "table3"):
        assert f"{step}: done" in call.stdout, step
    for name in (
        "model/generative.pt",
        "model/motion.pt",
        "model/detail.pt",
        "table1.md",
        "table3.md",
        "detail_report.md",
    ):
        path = out / name
        assert path.is_file() and path.stat().st_size < 16 * 2**20, name
    # The toy set's test clip is rolled out by both tables.
    assert "| c | 16 |" in (out / "table3.md").read_text()


def test_the_simulator_s_speed_call_runs_the_corpus_and_the_table(tmp_path):
    """``sim-speed`` at toy size: the corpus end to end from the command line (timed, its
    manifest brought back), then bench/speed/sim_gpu.py's table; what a lent GPU runs in one
    call."""
    import json

    work, out = tmp_path / "work", tmp_path / "out"
    cmd = [
        sys.executable,
        str(SCRIPT),
        "sim-speed",
        "--tiny",
        "--device",
        "cpu",
        "--work",
        str(work),
        "--out",
        str(out),
        "--budget",
        "600",
        "--corpus-budget",
        "300",
        "--corpus-batch",
        "2",
        "--corpus-workers",
        "1",
        "--corpus-prepare-workers",
        "1",
        "--batches",
        "1,2",
        "--frames",
        "2",
        "--clips",
        "1",
        "--capture",
        "on",
        "--set",
        "settle_once=true",
    ]
    call = subprocess.run(cmd, capture_output=True, text=True, timeout=900)
    assert call.returncode == 0, call.stdout[-3000:] + call.stderr[-3000:]
    corpus = json.loads((out / "corpus.json").read_text())
    assert corpus["exit"] == 0 and corpus["complete"] and corpus["clips_done"] == 2
    assert corpus["seconds"] > 0 and (out / "corpus_manifest.json").is_file()
    manifest = json.loads((out / "corpus_manifest.json").read_text())
    assert manifest["config"]["cloth"]["settle_once"] is True  # --set reached the corpus
    table = json.loads((out / "sim_gpu.json").read_text())
    runs = [r for r in table["runs"] if "skipped" not in r]
    assert [r["batch"] for r in runs] == [1, 2] and all(r["frames_per_second"] > 0 for r in runs)
    assert "first simulated frames after" in (out / "sim_gpu.md").read_text()
