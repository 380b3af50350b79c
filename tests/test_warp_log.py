"""warp's banner and kernel-load messages stay off standard output, where loosefit's
commands write their results."""

from __future__ import annotations

import os
import subprocess
import sys

from tests.conftest import REPO

# loosefit's closest-point query on one triangle: importing it imports warp, building the
# surface initialises warp (its banner), the query loads a kernel module (its load time)
QUERY = """
import numpy as np
from loosefit.geometry.query import Surface
surface = Surface(np.eye(3, dtype=np.float32), np.array([[0, 1, 2]]))
hit = surface.query(np.array([[1.0, 1.0, 1.0]], np.float32), sign="normal")
print(hit.faces.tolist())
"""


def _python(code: str) -> subprocess.CompletedProcess:
    """``code`` run by a fresh Python on this checkout's loosefit."""
    env = {**os.environ, "PYTHONPATH": str(REPO / "src")}
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, env=env, timeout=600
    )


def test_warp_messages_go_to_standard_error_and_standard_output_keeps_the_result():
    run = _python(QUERY)
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout == "[0]\n"
    assert "Warp " in run.stderr and "initialized" in run.stderr  # it did initialise
    assert "Module loosefit.geometry.query" in run.stderr


def test_a_program_s_own_warp_logger_is_left_in_place():
    code = """
import warp
class Mine:
    def debug(self, m): pass
    def info(self, m): pass
    def warning(self, m, category=None, stacklevel=1): pass
    def error(self, m): pass
mine = Mine()
warp.set_logger(mine)
from loosefit.warp_log import import_warp
import_warp()
print(warp.get_logger() is mine)
"""
    run = _python(code)
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout == "True\n"
