"""A fast salsa spin at fixed and at adaptive substeps: does the skirt hold?

Usage:
    .venv/bin/python bench/data/spin_substeps.py [--job chain_60_03_60_07_61_03_61_07]
        [--start 1140] [--stop 1260] [--substeps 20] [--max-substeps 20]
        [--bvh ../shared/mocap/cmu-salsa] [--save out/spin.npz]

Simulates motion frames [start, stop) of one job of the ``salsa`` preset with
its cloth configuration (settled and blended in at ``start``), with
``--substeps`` per frame and, where the waistband moves fast, up to
``--max-substeps`` (equal: a fixed step). Prints the seconds, the substep
schedule, the per-10-frame maximum edge strain and the dataset's quality
figures. The default window holds the 26.6 rad/s spin of 61_03 in the held-out
chain. ``--save`` writes the simulated frames as a sequence for
``loosefit render --sequence``. docs/use/DATASET.md quotes its output; each run
takes one core.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import time

import numpy as np
import torch

from loosefit.body.avatar import Avatar, AvatarConfig
from loosefit.fitting.place import fit_skirt
from loosefit.garment.quality import edge_strain
from loosefit.sequence import GarmentSequence
from loosefit.sim.driver import simulate
from loosefit.sim.jobs import job_motion, plan_jobs
from loosefit.sim.presets import preset


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--job", default="chain_60_03_60_07_61_03_61_07")
    p.add_argument("--start", type=int, default=1140)
    p.add_argument("--stop", type=int, default=1260)
    p.add_argument("--substeps", type=int, default=20)
    p.add_argument("--max-substeps", type=int, default=None, help="default: the preset's")
    p.add_argument("--bvh", default=None, help="the salsa BVH folder (default ../shared/...)")
    p.add_argument("--save", default=None, help="write the frames here (a sequence .npz)")
    args = p.parse_args()

    torch.set_num_threads(1)
    config = preset("salsa", args.bvh)
    jobs = {j.name: j for j in plan_jobs(config)}
    if args.job not in jobs:
        raise SystemExit(f"--job: expected one of {sorted(jobs)}, found {args.job!r}")
    job = jobs[args.job]
    avatar = Avatar(AvatarConfig(shape=dict(config.shape)))
    template = fit_skirt(avatar, config.garment)
    motion = job_motion(config, job, avatar).slice(args.start, args.stop)
    most = config.cloth.max_substeps if args.max_substeps is None else args.max_substeps
    cloth = dataclasses.replace(
        config.cloth, seed=job.seed, substeps=args.substeps, max_substeps=max(most, args.substeps)
    )
    t0 = time.perf_counter()
    result = simulate(avatar, template, motion, cloth)
    wall = time.perf_counter() - t0

    g = result.garment_vertices  # (T, V, 3)
    strain = edge_strain(g, template)[0].max(1)  # (T,), the waistband's own edges left out
    print(f"machine: {platform.platform()}, {os.cpu_count()} cores; device {cloth.device}")
    print(
        f"job {job.name}, motion frames {args.start}-{args.stop}, {template.num_vertices} "
        f"vertices; substeps {cloth.substeps}..{cloth.max_substeps}: mean "
        f"{result.stats['substeps_mean']:.1f}, max {result.stats['substeps_max']}"
    )
    frames = result.preroll_frames + motion.num_frames
    print(f"{wall:.0f} s, {wall / frames:.2f} s per frame ({frames} frames with the preroll)")
    blocks = [
        f"{args.start + i}: {strain[i : i + 10].max():.2f}" for i in range(0, len(strain), 10)
    ]
    print("max edge strain per 10 frames:", ", ".join(blocks))
    bad = np.nonzero(strain > 0.5)[0]
    print(
        f"frames with an edge stretched > 50 %: {len(bad)}"
        + (f", first {args.start + bad[0]}" if len(bad) else "")
    )
    scalars = {k: round(float(v), 4) for k, v in result.quality.items() if np.ndim(v) == 0}
    print("quality:", scalars)
    if args.save:
        source = f"newton-vbd, substeps {cloth.substeps}..{cloth.max_substeps}"
        avatar_spec = {"rig": avatar.config.rig, "shape": avatar.shape}
        GarmentSequence(motion, template, g, avatar_spec, source).save(args.save)
        print(f"wrote {args.save}")


if __name__ == "__main__":
    main()
