"""scripts/gpu_pipeline.py at toy size on the CPU: every step, a budget that runs out, resume."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "gpu_pipeline.py"


def pipeline(work: Path, out: Path, budget: float) -> subprocess.CompletedProcess:
    cmd = [sys.executable, str(SCRIPT), "run", "--tiny", "--device", "cpu", "--work", str(work),
           "--out", str(out), "--budget", str(budget)]  # fmt: skip
    return subprocess.run(cmd, capture_output=True, text=True, timeout=900)


def test_the_pipeline_runs_in_budgeted_calls_and_brings_back_the_model(tmp_path):
    work, out = tmp_path / "work", tmp_path / "out"
    # A call too short for the whole pipeline stops inside a step and says to call again.
    first = pipeline(work, out, 45)
    assert first.returncode == 3, first.stdout + first.stderr
    assert "call again" in first.stdout
    assert (work / "simulate.done").is_file()  # the simulation fits in 35 s; training does not
    assert (out / "manifest.json").is_file() and (out / "logs.txt").is_file()
    # The next call goes on from there (the simulation is not run again) to the end.
    second = pipeline(work, out, 600)
    assert second.returncode == 0, second.stdout + second.stderr
    assert "simulate (" not in second.stdout and second.stdout.strip().endswith("done")
    for name in ("model/generative.pt", "model/motion.pt", "table1.md", "table3.md",
                 "generative_report.md", "motion_report.md", "BATCH_INFERENCE.md"):  # fmt: skip
        path = out / name
        assert path.is_file() and path.stat().st_size < 16 * 2**20, name
    assert "spin_001" in (out / "table1.md").read_text()
    # Everything done: a third call does nothing.
    third = pipeline(work, out, 60)
    assert third.returncode == 0 and "] " not in third.stdout
