"""How many threads torch uses while a model animates: the default policy and ``threads=``.

A frame's tensors are small (a 2,352-vertex garment, small networks) and the rollout
already runs its later stages (edge lengths, collision handling) on a second Python thread
beside the motion stage, each with its own team of torch's intra-op (OpenMP) threads. More
intra-op threads than free cores then cost far more than they save: every operation
waits for its team's slowest thread, and a thread that another program's work has taken
off its core holds up the rest (with OpenMP's idle threads sleeping rather than spinning,
too). On dev-cpu (2 cores) under load, torch's default of a thread a core made
``animate`` 1.5-1.9x slower than one thread, at 2x the CPU time (a user saw 6x); on the
quiet machine two threads were 1.22x faster than one (docs/results/BENCHMARKS.md, "Threads";
``bench/speed/animate_threads.py``).

The default (:func:`default_threads`) is therefore the free cores, counted from the
machine's load: ``round(cores - load)`` where ``cores`` are the ones this process may run
on (its CPU affinity and a container's CPU quota) and ``load`` the one-minute load
average, at least 1 and at most :data:`MOST_THREADS`; never more than torch's own count
(a smaller ``torch.set_num_threads(k)`` of yours stays; a larger one is lowered like
torch's default), and torch's count as it is when ``OMP_NUM_THREADS`` or
``MKL_NUM_THREADS`` is set (you chose it). ``threads=N`` (the API) or ``--threads N``
(the commands) overrides it.

The setting is **scoped**: :func:`inference_threads` sets torch's count for one
``animate`` call and puts the previous count back after it.

Thread counts change the order of floating-point sums, so two counts give garments that
differ by float rounding (under 1e-6 m) before collision handling and, since collision
handling is not continuous in its input, by up to about 2 mm at a few vertices after it;
one count gives the same garments, bit for bit, whoever chose it. For bit-identical reruns
on machines under different loads, pass a fixed count.
"""

from __future__ import annotations

import math
import numbers
import os
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

from loosefit.errors import LoosefitInputError

MOST_THREADS = 4  # the default's ceiling, for a frame's small tensors (not measured past 2 cores)
USER_THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS")  # torch reads these at start
CGROUP_CPU_MAX = Path("/sys/fs/cgroup/cpu.max")  # a container's CPU quota (cgroup v2)


def default_threads(cores: int, load: float, current: int, env: Mapping[str, str]) -> int:
    """The default intra-op thread count for inference (pure: the caller reads the machine).

    Args:
        cores: the cores this process may run on (:func:`machine_cores`).
        load: the one-minute load average (``os.getloadavg()[0]``), this process included.
        current: torch's thread count now (``torch.get_num_threads()``).
        env: the environment (``os.environ``).

    Returns:
        ``current`` when ``env`` sets ``OMP_NUM_THREADS`` or ``MKL_NUM_THREADS`` (the user's
        choice); otherwise the free cores, ``round(cores - load)``, at least 1, at most
        :data:`MOST_THREADS` and at most ``current``.
    """
    if user_thread_variable(env) is not None:
        return max(1, current)
    free = math.floor(cores - max(0.0, load) + 0.5)
    return max(1, min(free, MOST_THREADS, cores, current))


def user_thread_variable(env: Mapping[str, str]) -> str | None:
    """The first of ``OMP_NUM_THREADS`` and ``MKL_NUM_THREADS`` that ``env`` sets, or None."""
    return next((name for name in USER_THREAD_VARIABLES if env.get(name, "").strip()), None)


def cpu_quota(text: str) -> int | None:
    """The cores a cgroup v2 ``cpu.max`` line allows (``"200000 100000"`` -> 2), rounded
    up; None for no quota (``"max 100000"``) or a line that is not one."""
    parts = text.split()
    if len(parts) != 2 or parts[0] == "max":
        return None
    try:
        quota, period = int(parts[0]), int(parts[1])
    except ValueError:
        return None
    return max(1, math.ceil(quota / period)) if quota > 0 and period > 0 else None


def machine_cores() -> int:
    """The cores this process may run on: its CPU affinity (all cores where the platform
    has none), fewer under a container's CPU quota."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # macOS, Windows
        cores = os.cpu_count() or 1
    try:
        quota = cpu_quota(CGROUP_CPU_MAX.read_text())
    except OSError:
        quota = None
    return max(1, min(cores, quota or cores))


def machine_load() -> float:
    """The one-minute load average (0 where the platform has none)."""
    try:
        return os.getloadavg()[0]
    except (AttributeError, OSError):  # Windows
        return 0.0


def check_threads(threads, source: str = "threads") -> int:
    """``threads`` as an int >= 1.

    Raises:
        LoosefitInputError: anything else (naming ``source``, e.g. ``--threads``).
    """
    if isinstance(threads, bool) or not isinstance(threads, numbers.Integral) or threads < 1:
        raise LoosefitInputError(source, "threads", "a whole number, at least 1", repr(threads))
    return int(threads)


def inference_threads_for(threads: int | None, source: str = "threads") -> int:
    """The thread count to animate with: ``threads`` checked, or the default policy on
    this machine now (None)."""
    import torch

    if threads is not None:
        return check_threads(threads, source)
    return default_threads(machine_cores(), machine_load(), torch.get_num_threads(), os.environ)


@contextmanager
def inference_threads(threads: int | None = None, source: str = "threads") -> Iterator[int]:
    """Within the block, torch runs with ``threads`` intra-op threads (None: the default
    policy, :func:`default_threads`); after it, torch's count before comes back.

    Yields:
        The count set.

    Raises:
        LoosefitInputError: ``threads`` not an int >= 1 (naming ``source``).
    """
    import torch

    n = inference_threads_for(threads, source)
    before = torch.get_num_threads()
    if n != before:
        torch.set_num_threads(n)
    try:
        yield n
    finally:
        if torch.get_num_threads() != before:
            torch.set_num_threads(before)
