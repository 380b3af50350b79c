"""Seconds per frame of the Newton VBD cloth simulation, and its quality figures.

Usage:
    .venv/bin/python bench/speed/sim_speed.py [--motion spin] [--frames 60] [--style flared]
        [--resolution cpu] [--device cpu] [--no-self-contact] [--batch 1,16,64]

Prints the machine, the configuration, seconds per 30-fps frame (settle and
blend-in included, warp kernels already compiled) and the quality numbers that
a dataset records per clip. docs/results/BENCHMARKS.md quotes its output.

``--batch K1,K2,...`` also times K copies of the clip (each its own jitter seed)
simulated at once as worlds of one model (``loosefit simulate --batch K``): the
seconds per frame per clip (the batch's shared out) and clips of this length per hour.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import torch

from loosefit.body.avatar import Avatar
from loosefit.fitting.place import fit_skirt
from loosefit.garment.skirt import SkirtConfig
from loosefit.motion.motions import load_motion
from loosefit.sim.cloth_config import ClothConfig
from loosefit.sim.driver import simulate, simulate_batch


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--motion", default="spin")
    p.add_argument("--frames", type=int, default=60)
    p.add_argument("--style", default="flared")
    p.add_argument("--resolution", default="cpu")
    p.add_argument("--device", default="cpu")
    p.add_argument("--no-self-contact", action="store_true")
    p.add_argument("--batch", default="", help="comma-separated clip counts simulated at once")
    args = p.parse_args()

    torch.set_num_threads(1)
    avatar = Avatar()
    template = fit_skirt(avatar, SkirtConfig.preset(args.resolution, args.style))
    motion = load_motion(args.motion, avatar, max_frames=args.frames)
    config = ClothConfig(device=args.device, self_contact=not args.no_self_contact)
    # Compile warp's kernels outside the timing.
    simulate(
        avatar,
        template,
        motion.slice(0, 2),
        ClothConfig(**{**config.__dict__, "settle_seconds": 0.0, "blend_seconds": 0.0}),
    )
    t0 = time.perf_counter()
    result = simulate(avatar, template, motion, config)
    wall = time.perf_counter() - t0
    q = result.quality
    print(
        f"machine: {platform.platform()}, {platform.processor() or 'cpu'}, {os.cpu_count()} cores"
    )
    print(f"device: {args.device}; torch threads: {torch.get_num_threads()}")
    print(
        f"garment: {args.style} ({args.resolution}), {template.num_vertices} vertices; "
        f"motion: {args.motion}, {motion.num_frames} frames + {result.preroll_frames} preroll"
    )
    print(
        f"substeps {config.substeps}, iterations {config.iterations}, "
        f"self-contact {config.self_contact}"
    )
    print(f"seconds per frame: {result.seconds_per_frame:.3f} (wall {wall:.1f} s in all)")
    print(
        f"inside body: max {q['inside_max']:.4f} mean {q['inside_mean']:.5f}; "
        f"strain p50 {q['strain_p50']:.3f} p95 {q['strain_p95']:.3f} p99 {q['strain_p99']:.3f} "
        f"max {q['strain_max']:.3f}; max speed {q['max_speed']:.2f} m/s; NaN {q['nan_count']}"
    )
    per_clip = wall  # seconds per clip of this length, build and quality figures included
    print(f"batch 1: {per_clip:.1f} s per clip, {3600 / per_clip:.1f} clips per hour")
    for k in [int(x) for x in args.batch.split(",") if x]:
        t0 = time.perf_counter()
        results = simulate_batch(avatar, template, [motion] * k, config, seeds=list(range(k)))
        wall = time.perf_counter() - t0
        worst = max(r.quality["strain_p99"] for r in results)
        print(
            f"batch {k}: {results[0].seconds_per_frame:.4f} s per frame per clip, "
            f"{wall / k:.2f} s per clip, {3600 * k / wall:.1f} clips per hour "
            f"(wall {wall:.1f} s; worst strain p99 {worst:.3f})"
        )


if __name__ == "__main__":
    main()
