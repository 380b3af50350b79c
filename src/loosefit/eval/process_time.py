"""The CPU time of a process and of its children, read from Linux's ``/proc``.

What a browser drawing the viewer costs: :func:`descendants` finds every process a launcher
started, :func:`gpu_process` Chromium's GPU process among them, :func:`cpu_seconds` the
user and system seconds of one.
"""

from __future__ import annotations

import os
from pathlib import Path


def processes() -> dict[int, tuple[int, bytes]]:
    """Every process's id -> (its parent's id, its command line), read from Linux's /proc."""
    found = {}
    for proc in Path("/proc").glob("[0-9]*"):
        try:
            cmdline = (proc / "cmdline").read_bytes()  # Chromium rewrites it: one string
            parent = int((proc / "stat").read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, ValueError, IndexError):
            continue
        found[int(proc.name)] = (parent, cmdline)
    return found


def descendants(pid: int) -> list[int]:
    """``pid`` and the ids of its descendants (the launcher may be a script)."""
    procs = processes()

    def under(p: int) -> bool:
        while p in procs and p != pid:
            p = procs[p][0]
        return p == pid

    return [p for p in procs if under(p)]


def gpu_process(pid: int) -> int | None:
    """The id of Chromium's GPU process (``--type=gpu-process``) among the descendants of
    ``pid``; None when none is."""
    procs = processes()
    gpu = [p for p in descendants(pid) if b"--type=gpu-process" in procs.get(p, (0, b""))[1]]
    return gpu[0] if gpu else None


def cpu_seconds(pid: int | None) -> float:
    """User and system CPU seconds of a process so far (0 when there is none or it ended)."""
    if pid is None:
        return 0.0
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
