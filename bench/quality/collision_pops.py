"""Flicker that collision handling adds: vertices that jump in one frame and back in the next.

Animates each motion with the whole pipeline and again without collision handling, and
counts the vertex-frames whose acceleration (second difference of positions, m per frame
squared) collision handling raised by more than 1 and 2 cm: a vertex pushed out of a limb
one way in a frame and the other way in the next, or walked through a body part in one
frame and not the next. Also the collision handling's CPU time per frame, the vertices
it leaves inside the body and the longest edge against its rest length (what a push tears).
``--variants`` compares settings of ``CollisionConfig`` (``name:field=value,...``).
docs/results/BENCHMARKS.md quotes it::

    OMP_NUM_THREADS=1 python bench/quality/collision_pops.py ../shared/mocap/cmu-salsa/60_01.bvh \\
        ../shared/mocap/cmu-ballet/05_20.bvh --frames 150
"""

from __future__ import annotations

import argparse
import dataclasses
import platform
import time

import numpy as np
import torch

import loosefit
from loosefit.geometry.edges import unique_edges
from loosefit.inference.stages import Stages
from loosefit.motion.motions import load_motion


def accelerations(x: np.ndarray) -> np.ndarray:
    """(T, V, 3) positions -> (T - 2, V) the length of each vertex's second difference."""
    return np.linalg.norm(x[2:] - 2 * x[1:-1] + x[:-2], axis=-1)


def parse_variant(spec: str) -> tuple[str, dict]:
    """``name:field=value,...`` -> (name, {field: value}) (values as Python literals)."""
    name, _, fields = spec.partition(":")
    kw = {}
    for item in filter(None, fields.split(",")):
        key, _, value = item.partition("=")
        kw[key] = {"true": True, "false": False}.get(value.lower(), None)
        if kw[key] is None:
            kw[key] = float(value) if "." in value or "e" in value else int(value)
    return name, kw


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("motions", nargs="+", help="motion specs (BVH paths, spin, dance:SEED)")
    p.add_argument("--checkpoint", default="checkpoints/salsa/motion.pt")
    p.add_argument("--start-frame", type=int, default=10)
    p.add_argument("--frames", type=int, default=150)
    p.add_argument(
        "--variants",
        nargs="*",
        default=["default", "not sticky:sticky=false"],
        help="CollisionConfig settings, name:field=value,...",
    )
    args = p.parse_args()
    torch.set_num_threads(1)
    model = loosefit.load(args.checkpoint).model
    print(
        f"{time.strftime('%Y-%m-%d')}, {platform.machine()}, torch {torch.__version__}, one "
        f"thread; {args.frames} frames of each motion from frame {args.start_frame}"
    )
    edges, _ = unique_edges(np.asarray(model.template.faces))
    rest = np.asarray(model.template.rest)
    rest_lengths = np.linalg.norm(rest[edges[:, 0]] - rest[edges[:, 1]], axis=1)  # (E,)
    print(
        "| motion | collision handling | CPU ms/frame | vertex-frames +1 cm | +2 cm | largest "
        "| 99.9th pct | vertex-frames inside after | longest edge / rest | frames with an "
        "edge > 2x |"
    )
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for spec in args.motions:
        motion = load_motion(
            spec,
            model.avatar(),
            fps=model.fps,
            start_frame=args.start_frame,
            max_frames=args.frames,
        )
        free = Stages(overlap=False, collision=False)
        before = accelerations(np.asarray(model.animate(motion, stages=free).vertices))
        for variant in args.variants:
            name, kw = parse_variant(variant)
            with model.configured(collision=dataclasses.replace(model.collision, **kw)) as m:
                r = m.animate(motion, stages=Stages(overlap=False))
            x = np.asarray(r.vertices)
            extra = accelerations(x) - before  # (T - 2, V) m
            stretch = np.linalg.norm(x[:, edges[:, 0]] - x[:, edges[:, 1]], axis=-1) / rest_lengths
            inside = sum(c["inside_after"] for c in r.collisions)
            ms = 1e3 * r.stage_cpu_seconds["collision"] / motion.num_frames
            pct = 1e3 * np.quantile(extra, 0.999)
            print(
                f"| {motion.name} | {name} | {ms:.1f} | {(extra > 0.01).sum()} "
                f"| {(extra > 0.02).sum()} | {100 * extra.max():.1f} cm | {pct:.1f} mm "
                f"| {inside} | {stretch.max():.2f} | {(stretch.max(1) > 2).sum()} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
