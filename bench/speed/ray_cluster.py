"""``loosefit simulate --ray``: how fast a bad address fails, and what Ray costs on one machine.

1. The address check (:func:`loosefit.sim.cluster.preflight`) against a refused port, a host
   that does not resolve, and a port that accepts but never answers; then the whole command
   line, ``loosefit simulate --preset tiny --ray 127.0.0.1:PORT`` (Python's imports
   included), to its error.
2. With ``--compare``: the ``tiny`` preset made by the local runner (``--workers 2``) and on
   a Ray instance of two CPUs on this machine; wall time of each, and whether the two data
   sets are the same, bit for bit. docs/use/CLUSTER.md quotes its output::

    .venv/bin/python bench/speed/ray_cluster.py --compare
"""

from __future__ import annotations

import argparse
import json
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.sim.cluster import ClusterConfig, preflight
from loosefit.sim.generate import generate
from loosefit.sim.presets import preset


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _time_refusal(address: str, timeout: float) -> tuple[float, str]:
    t0 = time.perf_counter()
    try:
        preflight(ClusterConfig(address, connect_timeout=timeout))
    except LoosefitInputError as exc:
        return time.perf_counter() - t0, exc.found
    raise SystemExit(f"{address}: expected a refusal")


def _same(a: Path, b: Path) -> bool:
    """The same sequences and template, bit for bit, and the same split."""
    ma, mb = (json.loads((p / "manifest.json").read_text()) for p in (a, b))
    if ma["split"] != mb["split"]:
        return False
    for rel in ["template.npz", *(f"sequences/{n}.npz" for n in ma["sequences"])]:
        with np.load(a / rel) as x, np.load(b / rel) as y:
            if sorted(x.files) != sorted(y.files):
                return False
            if not all(np.array_equal(x[k], y[k]) for k in x.files):
                return False
    return True


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--compare",
        action="store_true",
        help="also make the tiny preset locally and on Ray (minutes)",
    )
    args = parser.parse_args()

    port = _free_port()
    with socket.socket() as silent:
        silent.bind(("127.0.0.1", 0))
        silent.listen()
        cases = {
            "refused port": (f"127.0.0.1:{port}", 5.0),
            "unknown host": ("no-such-host.invalid:6379", 5.0),
            "silent port": (f"127.0.0.1:{silent.getsockname()[1]}", 5.0),
        }
        for what, (address, timeout) in cases.items():
            seconds, found = _time_refusal(address, timeout)
            print(f"{what:<14} {seconds:7.3f} s  ({found})")
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        cmd = [
            sys.executable,
            "-m",
            "loosefit.cli",
            "simulate",
            "--preset",
            "tiny",
            "--out",
            str(Path(tmp) / "x"),
            "--ray",
            f"127.0.0.1:{port}",
        ]
        run = subprocess.run(cmd, capture_output=True, text=True)
        seconds = time.perf_counter() - t0
        print(f"command line   {seconds:7.3f} s  (exit {run.returncode}, imports included)")

    if not args.compare:
        return
    import ray

    with tempfile.TemporaryDirectory() as tmp:
        local, on_ray = Path(tmp) / "local", Path(tmp) / "ray"
        t0 = time.perf_counter()
        generate(preset("tiny"), local, workers=2, progress=False)
        t_local = time.perf_counter() - t0
        t0 = time.perf_counter()
        ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
        t_start = time.perf_counter() - t0
        t0 = time.perf_counter()
        generate(preset("tiny"), on_ray, progress=False, cluster=ClusterConfig())
        t_ray = time.perf_counter() - t0
        ray.shutdown()
        print(f"tiny, --workers 2:            {t_local:6.1f} s")
        print(f"tiny, Ray (2 CPUs, this one): {t_ray:6.1f} s (+ {t_start:.1f} s to start Ray)")
        print(f"the same data set, bit for bit: {_same(local, on_ray)}")


if __name__ == "__main__":
    main()
