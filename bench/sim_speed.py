"""Seconds per frame of the Newton VBD cloth simulation, and its quality figures.

Usage:
    .venv/bin/python bench/sim_speed.py [--motion spin] [--frames 60] [--style flared]
        [--resolution cpu] [--device cpu] [--no-self-contact]

Prints the machine, the configuration, seconds per 30-fps frame (settle and
blend-in included, warp kernels already compiled) and the quality numbers that
a dataset records per clip. docs/BENCHMARKS.md quotes its output.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import torch

from loosefit.body.avatar import Avatar
from loosefit.body.motions import load_motion
from loosefit.dress import fit_skirt
from loosefit.garment.skirt import SkirtConfig
from loosefit.sim.cloth import ClothConfig, simulate


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--motion", default="spin")
    p.add_argument("--frames", type=int, default=60)
    p.add_argument("--style", default="flared")
    p.add_argument("--resolution", default="cpu")
    p.add_argument("--device", default="cpu")
    p.add_argument("--no-self-contact", action="store_true")
    args = p.parse_args()

    torch.set_num_threads(1)
    avatar = Avatar()
    template = fit_skirt(avatar, SkirtConfig.preset(args.resolution, args.style))
    motion = load_motion(args.motion, avatar, max_frames=args.frames)
    config = ClothConfig(device=args.device, self_contact=not args.no_self_contact)
    # Compile warp's kernels outside the timing.
    simulate(avatar, template, motion.slice(0, 2), ClothConfig(**{**config.__dict__,
             "settle_seconds": 0.0, "blend_seconds": 0.0}))  # fmt: skip
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


if __name__ == "__main__":
    main()
