"""The built wheel, installed in a fresh environment, runs the API and the demo with no checkout."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.heavy  # builds a wheel and installs it into a fresh environment

REPO = Path(__file__).resolve().parents[1]

API_EXAMPLE = """
import loosefit
model = loosefit.load()
result = model.animate("kick", frames=12)
result.export("kick.usda")
result.save("kick.npz")
print("FILE", loosefit.__file__)
print("SHAPE", result.vertices.shape)
"""


def readme_example() -> str:
    """The README's Python example, as a user copies it (its first ``python`` block)."""
    text = (REPO / "README.md").read_text()
    return text.split("```python\n", 1)[1].split("```", 1)[0]


def _run(cmd: list, cwd: Path | None = None) -> str:
    run = subprocess.run([str(c) for c in cmd], cwd=cwd, capture_output=True, text=True)
    assert run.returncode == 0, f"{cmd}\n{run.stdout[-3000:]}\n{run.stderr[-3000:]}"
    return run.stdout


def test_the_wheel_runs_the_api_and_the_demo_without_a_checkout(tmp_path):
    # 1. the wheel, from this source tree
    dist = tmp_path / "dist"
    _run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--no-deps",
            "--no-build-isolation",
            "-q",
            "-w",
            dist,
            REPO,
        ]
    )
    (wheel,) = dist.glob("loosefit-*.whl")
    # 2. a fresh environment: it sees the dependencies installed beside this interpreter
    #    (plain paths in a .pth, so their own .pth files, the editable checkout's among
    #    them, are not read) and the wheel installed into it, nothing else
    venv = tmp_path / "venv"
    _run([sys.executable, "-m", "venv", "--without-pip", venv])
    (site,) = venv.glob("lib/python*/site-packages")
    deps = [p for p in sys.path if p.endswith("site-packages")]
    (site / "_deps.pth").write_text("\n".join(deps) + "\n")
    # --ignore-installed: never touch the loosefit installed beside this interpreter
    _run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "--no-deps",
            "--ignore-installed",
            "-q",
            "--prefix",
            venv,
            wheel,
        ]
    )
    # 3. in an empty folder: the README's API example, then the main job
    empty = tmp_path / "elsewhere"
    empty.mkdir()
    python = venv / "bin" / "python"
    out = dict(
        line.split(" ", 1)
        for line in _run([python, "-c", API_EXAMPLE], cwd=empty).splitlines()
        if line.startswith(("FILE ", "SHAPE "))
    )
    assert out["FILE"].startswith(str(site)), out  # the installed copy, not the checkout
    assert out["SHAPE"] == "(12, 2352, 3)"
    assert (empty / "kick.usda").is_file() and (empty / "kick.npz").is_file()
    # the README's example itself, word for word, with no ../shared and no checkout
    _run([python, "-c", readme_example()], cwd=empty)
    assert (empty / "dance.usdc").is_file()
    _run(
        [
            python,
            venv / "bin" / "loosefit",
            "demo",
            "--motion",
            "kick",
            "--max-frames",
            "15",
            "--size",
            "48",
            "--views",
            "front",
            "--out",
            "demo",
        ],
        cwd=empty,
    )
    for name in ("video.mp4", "demo.usdc", "demo.pc2", "sequence.npz"):
        assert (empty / "demo" / name).is_file(), name
