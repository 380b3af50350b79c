"""Where collision handling's time goes: the body's BVH refit and each kind of closest-point query.

Animates a motion with the whole pipeline on one thread (the stages one after another) and
times, per frame, every ``Surface.refit`` and every ``Surface.query`` grouped by the
method that asked (the solve, the face samples, the last projection, the mending) and its
inside test (``normal`` or ``winding``). docs/results/BENCHMARKS.md quotes it::

    .venv/bin/python bench/speed/collision_profile.py \\
        --motion ../shared/mocap/cmu-salsa/60_01.bvh --start-frame 10 --frames 150
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from collections import defaultdict

import torch

import loosefit
from loosefit.geometry import query
from loosefit.inference.stages import Stages
from loosefit.inference.stages.collision import COLLISION_SETTINGS, collision_setting
from loosefit.motion.motions import load_motion


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--checkpoint", default="checkpoints/salsa/motion.pt")
    p.add_argument("--motion", default="../shared/mocap/cmu-salsa/60_01.bvh")
    p.add_argument("--start-frame", type=int, default=10)
    p.add_argument("--frames", type=int, default=150)
    p.add_argument(
        "--no-fast-path", action="store_true", help="collision handling without its fast path"
    )
    p.add_argument(
        "--collision",
        choices=COLLISION_SETTINGS,
        default="full",
        help="collision handling's setting (realtime: one round of each)",
    )
    args = p.parse_args()
    torch.set_num_threads(1)
    model = loosefit.load(args.checkpoint).model
    if args.no_fast_path:
        model.collision = dataclasses.replace(model.collision, fast=False)
    model.collision = collision_setting(model.collision, args.collision)
    motion = load_motion(
        args.motion,
        model.avatar(),
        fps=model.fps,
        start_frame=args.start_frame,
        max_frames=args.frames,
    )
    stages = Stages(overlap=False)
    model.animate(motion.slice(0, min(20, motion.num_frames)), stages=stages)  # warm-up

    # (asker, sign) -> calls, points, seconds, CPU seconds (the thread's)
    queries = defaultdict(lambda: [0, 0, 0.0, 0.0])
    refits = [0.0, 0.0]  # seconds, CPU seconds
    ask, refit = query.Surface.query, query.Surface.refit

    def timed_query(self, points, max_distance=1.0e3, sign="winding", accuracy=2.0, hint=None):
        asker = sys._getframe(1).f_code.co_name
        if asker in ("signed_distances", "_signed", "_ask"):  # the helpers: name who called
            asker = sys._getframe(2).f_code.co_name
        t, c = time.perf_counter(), time.thread_time()
        hit = ask(self, points, max_distance, sign, accuracy, hint)
        entry = queries[(asker, sign)]
        entry[0] += 1
        entry[1] += len(points)
        entry[2] += time.perf_counter() - t
        entry[3] += time.thread_time() - c
        return hit

    def timed_refit(self, vertices):
        t, c = time.perf_counter(), time.thread_time()
        refit(self, vertices)
        refits[0] += time.perf_counter() - t
        refits[1] += time.thread_time() - c

    query.Surface.query, query.Surface.refit = timed_query, timed_refit
    try:
        result = model.animate(motion, stages=stages)
    finally:
        query.Surface.query, query.Surface.refit = ask, refit
    n = motion.num_frames
    stage_ms = {k: round(1e3 * v / n, 1) for k, v in (result.stage_seconds or {}).items()}
    cpu_ms = {k: round(1e3 * v / n, 1) for k, v in (result.stage_cpu_seconds or {}).items()}
    print(
        f"{motion.name}, {n} frames, one thread, fast path {model.collision.fast}, "
        f"{args.collision} collision handling; ms per "
        f"frame of each stage: {stage_ms}, CPU: {cpu_ms}"
    )
    print(f"body BVH refit: {1e3 * refits[0] / n:.1f} ms per frame (CPU {1e3 * refits[1] / n:.1f})")
    print(
        "| asked by | inside test | queries per frame | points per query | ms per frame "
        "| CPU ms per frame |"
    )
    print("|---|---|---:|---:|---:|---:|")
    for (asker, sign), (calls, points, seconds, cpu) in sorted(queries.items(), key=_cpu):
        print(
            f"| {asker} | {sign} | {calls / n:.2f} | {points / max(calls, 1):.0f} "
            f"| {1e3 * seconds / n:.1f} | {1e3 * cpu / n:.1f} |"
        )


def _cpu(kv) -> float:
    """Most CPU time first."""
    return -kv[1][3]


if __name__ == "__main__":
    main()
