"""``animate``'s thread count: the default policy against one thread and all cores, on an
idle machine and under a background load this script makes itself.

Each configuration runs ``loosefit.load().animate(MOTION, frames=N, threads=...)`` in a
fresh process (torch's thread settings are per process): the model loaded and a short
warm-up first, untimed, then the rollout of ``--frames`` frames timed (wall clock and the
process's CPU time), ``--repeats`` times, the fastest kept. The thread count torch ran
with is read during the rollout. ``OMP_NUM_THREADS`` and ``MKL_NUM_THREADS`` are removed
from the children's environment (else the default keeps them).

``--omp-wait-policy PASSIVE`` runs them with OpenMP's idle threads sleeping at once
instead of spinning a while first.

The load: one busy-looping process per core (``os.cpu_count()``, no CPU affinity set),
started before the loaded runs, each ending by itself after ``--load-seconds`` at the most
and stopped when the runs are done; the runs wait until the one-minute load average has
risen to 80 % of the loops (at most ``--load-warmup`` seconds), as it has where other work
has been running for a while.

Writes the table to ``--out`` (markdown) and prints it; "ratio" is a row's seconds over
the fastest row's of its load condition. On dev-cpu (2 cores) it takes about 5 minutes::

    python bench/speed/animate_threads.py --machine dev-cpu --out docs/use/THREADS.md
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

BUSY_LOOP = "import time\nend = time.monotonic() + {seconds}\nwhile time.monotonic() < end: pass"


def child(threads: str, motion: str, frames: int, repeats: int) -> dict:
    """One configuration, in this process: the figures of the fastest of ``repeats`` runs."""
    import torch

    import loosefit

    asked = None if threads == "default" else int(threads)
    model = loosefit.load()
    model.animate(motion, frames=10, threads=asked)  # warm-up: kernels, caches
    seen = []

    def progress(done, total):
        if done == total:
            seen.append(torch.get_num_threads())

    best = None
    for _ in range(repeats):
        wall, cpu = time.perf_counter(), time.process_time()
        model.animate(motion, frames=frames, threads=asked, progress=progress)
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        if best is None or wall < best[0]:
            best = (wall, cpu)
    return {"asked": threads, "threads": seen[-1], "seconds": best[0], "cpu_seconds": best[1]}


def run_child(threads: str, args) -> dict:
    """One configuration in a fresh process, with the load average when it started."""
    env = {k: v for k, v in os.environ.items() if k not in ("OMP_NUM_THREADS", "MKL_NUM_THREADS")}
    if args.omp_wait_policy:  # read when OpenMP starts: set for the child, not here
        env["OMP_WAIT_POLICY"] = args.omp_wait_policy
    load = os.getloadavg()[0]
    command = [
        sys.executable,
        __file__,
        "--child",
        threads,
        "--motion",
        args.motion,
        "--frames",
        str(args.frames),
        "--repeats",
        str(args.repeats),
    ]
    out = subprocess.run(command, env=env, capture_output=True, text=True, check=False)
    if out.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed:\n{out.stderr[-3000:]}")
    row = json.loads(out.stdout.strip().splitlines()[-1])
    row["load_at_start"] = load
    print(f"  {row}", file=sys.stderr, flush=True)
    return row


def busy_loops(count: int, seconds: float) -> list[subprocess.Popen]:
    """``count`` busy-looping processes, each ending by itself after ``seconds``."""
    code = BUSY_LOOP.format(seconds=seconds)
    return [subprocess.Popen([sys.executable, "-c", code]) for _ in range(count)]


def wait_for_load(level: float, most: float) -> None:
    """Until the one-minute load average reaches ``level``, ``most`` seconds at the most."""
    end = time.monotonic() + most
    while os.getloadavg()[0] < level and time.monotonic() < end:
        time.sleep(2)


def measure(args) -> dict[str, list[dict]]:
    """Every configuration under every load condition asked."""
    configs = ["default", "1", str(os.cpu_count())]
    rows: dict[str, list[dict]] = {}
    for condition in args.conditions.split(","):
        print(f"{condition}:", file=sys.stderr, flush=True)
        loops = []
        try:
            if condition == "load":
                loops = busy_loops(os.cpu_count(), args.load_seconds)
                wait_for_load(0.8 * len(loops), args.load_warmup)
            elif condition != "idle":
                raise SystemExit(f"--conditions: expected idle and/or load, found {condition!r}")
            rows[condition] = [run_child(c, args) for c in configs]
        finally:
            for p in loops:
                p.terminate()
            for p in loops:
                p.wait()
    return rows


def table(rows: dict[str, list[dict]], args) -> str:
    """The markdown page: how it was made, then one row per configuration."""
    import torch

    cores = os.cpu_count()
    lines = [
        "# Inference threads: the default against one thread and all cores",
        "",
        f"Written by `python bench/speed/animate_threads.py {' '.join(sys.argv[1:])}` on "
        f"{args.machine} ({platform.machine()}, {cores} cores), {time.strftime('%Y-%m-%d')}, "
        f"torch {torch.__version__}. `loosefit.load().animate('{args.motion}', "
        f"frames={args.frames}, threads=...)`, each configuration in a fresh process, the "
        f"fastest of {args.repeats} run(s) after a warm-up; `load`: {cores} busy-looping "
        "processes beside it. `idle` is only as idle as the machine was: the load average "
        "when each run started is in its row. Ratio: the row's seconds over the fastest "
        "of its condition. OpenMP's wait policy (`OMP_WAIT_POLICY`): "
        f"{args.omp_wait_policy or 'not set (its default: spin a while, then sleep)'}.",
        "",
        "The default (`loosefit.inference.threads.default_threads`): the free cores, "
        "`round(cores - load average)`, at least 1 and at most 4, never more than torch's "
        "own count, and torch's count as it is where `OMP_NUM_THREADS` or `MKL_NUM_THREADS` "
        "is set; `--threads N` on `animate`, `demo` and `evaluate`, `threads=N` on "
        "`Animator.animate` and `animate_batch` choose instead, for that call alone (torch's "
        "count before comes back after it). The target: the default within 1.2x of the "
        "fastest row, idle and under load. What the figures mean, and earlier runs: "
        "[BENCHMARKS.md](BENCHMARKS.md#threads-how-many-animate-uses).",
        "",
        "| machine | date | torch | load condition | load average at start | threads asked "
        "| threads run | seconds | CPU seconds | frames/s | ratio to the best |",
        "|---|---|---|---|---:|---|---:|---:|---:|---:|---:|",
    ]
    for condition, found in rows.items():
        best = min(r["seconds"] for r in found)
        for r in found:
            asked = "default" if r["asked"] == "default" else r["asked"]
            lines.append(
                f"| {args.machine} | {time.strftime('%Y-%m-%d')} | {torch.__version__} "
                f"| {condition} | {r['load_at_start']:.1f} | {asked} | {r['threads']} "
                f"| {r['seconds']:.1f} | {r['cpu_seconds']:.1f} "
                f"| {args.frames / r['seconds']:.1f} | {r['seconds'] / best:.2f} |"
            )
    return "\n".join(lines) + "\n"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--motion", default="dance:20", help="what animate takes (30 fps)")
    p.add_argument("--frames", type=int, default=600)
    p.add_argument("--repeats", type=int, default=1, help="timed runs per configuration")
    p.add_argument("--conditions", default="idle,load", help="idle and/or load")
    p.add_argument("--load-seconds", type=float, default=600.0, help="a busy loop's longest life")
    p.add_argument("--load-warmup", type=float, default=60.0, help="most seconds to wait for it")
    p.add_argument(
        "--omp-wait-policy",
        default=None,
        choices=("PASSIVE", "ACTIVE"),
        help="OMP_WAIT_POLICY for the runs (default: not set)",
    )
    p.add_argument("--machine", default=platform.node(), help="the machine's name in the doc")
    p.add_argument("--out", default="docs/use/THREADS.md")
    p.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.child is not None:
        print(json.dumps(child(args.child, args.motion, args.frames, args.repeats)))
        return
    text = table(measure(args), args)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(text)
    print(text)


if __name__ == "__main__":
    main()
