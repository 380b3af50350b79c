"""The CPU time of a process and its children (loosefit.eval.process_time), on Linux."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest

from loosefit.eval.process_time import cpu_seconds, descendants, gpu_process, processes

pytestmark = pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="reads Linux's /proc")


def test_a_child_is_among_the_descendants():
    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(5)"])
    try:
        mine = descendants(os.getpid())
        assert os.getpid() in mine and child.pid in mine
        assert processes()[child.pid][0] == os.getpid()
        assert gpu_process(os.getpid()) is None  # no Chromium here
        assert child.pid not in descendants(child.pid + 10**7)
    finally:
        child.kill()
        child.wait()


def test_cpu_seconds_grow_with_work():
    before = cpu_seconds(os.getpid())
    end = time.process_time() + 0.3
    while time.process_time() < end:
        pass
    assert cpu_seconds(os.getpid()) - before >= 0.2
    assert cpu_seconds(None) == 0.0
    assert cpu_seconds(2**22 + 12345) == 0.0  # no such process
