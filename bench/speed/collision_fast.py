"""Collision handling's fast path against the path before it, on whole clips.

For each motion: the committed set's garments before collision handling (motion stage,
detail, edge lengths), then collision handling both ways on the same frames, one frame of
each in turn (so that a busy machine slows both alike): the thread CPU time per frame of
each, the largest distance between their garments (per vertex, over the clip), the frames
where it passes 0.5 mm, and the vertices left inside the body (``inside_after``) by each.
docs/design/notes/BENCHMARKS_HISTORY.md quotes it::

    OMP_NUM_THREADS=1 .venv/bin/python bench/speed/collision_fast.py \\
        ../shared/mocap/cmu-salsa/60_01.bvh ../shared/mocap/cmu-ballet/05_20.bvh spin
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

import loosefit
from loosefit.inference.stages import Stages
from loosefit.inference.stages.collision import CollisionConfig
from loosefit.motion.motions import load_motion


def compare(model, motion) -> dict:
    """Both paths over ``motion``'s frames; figures as the module says."""
    garments = model.animate(motion, stages=Stages(collision=False, overlap=False)).vertices
    colliders = []
    for fast in (False, True):
        with model.configured(CollisionConfig(fast=fast)):
            colliders.append(model.collider(motion))
    seconds, out, inside = [0.0, 0.0], [[], []], [0, 0]
    for t in range(motion.num_frames):
        for k in (0, 1) if t % 2 else (1, 0):
            start = time.thread_time()
            r = colliders[k](t, torch.from_numpy(garments[t]))
            seconds[k] += time.thread_time() - start
            out[k].append(r.vertices.numpy())
            inside[k] += r.inside_after
    gap = np.linalg.norm(np.stack(out[0]) - np.stack(out[1]), axis=-1)  # (T, V)
    n = motion.num_frames
    return {
        "frames": n,
        "ms_before": 1e3 * seconds[0] / n,
        "ms_fast": 1e3 * seconds[1] / n,
        "max_mm": 1e3 * float(gap.max()),
        "frames_over_half_mm": int((gap.max(1) > 5e-4).sum()),
        "inside_before": inside[0],
        "inside_fast": inside[1],
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("motion", nargs="+")
    p.add_argument("--checkpoint", default="checkpoints/salsa/motion.pt")
    p.add_argument("--start-frame", type=int, default=10)
    p.add_argument("--frames", type=int, default=300)
    args = p.parse_args()
    torch.set_num_threads(1)
    model = loosefit.load(args.checkpoint).model
    print(
        "| motion | frames | ms/frame before (CPU) | fast | largest gap (mm) | frames > 0.5 mm "
        "| inside after, before | fast |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for spec in args.motion:
        motion = load_motion(
            spec,
            model.avatar(),
            fps=model.fps,
            start_frame=args.start_frame,
            max_frames=args.frames,
        )
        r = compare(model, motion)
        print(
            f"| {motion.name} | {r['frames']} | {r['ms_before']:.1f} | {r['ms_fast']:.1f} "
            f"| {r['max_mm']:.3f} | {r['frames_over_half_mm']} | {r['inside_before']} "
            f"| {r['inside_fast']} |"
        )


if __name__ == "__main__":
    main()
