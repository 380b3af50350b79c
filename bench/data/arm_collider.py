"""The salsa cloth with the arms in the simulation's collider: does it hold?

Simulates windows of ``salsa`` preset jobs with ``arm_collision: true`` (everything else the
preset's: flattened overlaps, the pose correction, adaptive substeps) and prints the quality
figures of each (strain percentiles, the deepest vertex inside the body, the worst frame's
share deeper than 5 mm). docs/use/DATASET.md quotes its output; each window takes one core::

    .venv/bin/python bench/data/arm_collider.py 60_01:0:90 chain_60_03_60_07_61_03_61_07:0:60
    .venv/bin/python bench/data/arm_collider.py --preset dance --arms preset 05_16:0:122
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

import numpy as np
import torch

from loosefit.body.avatar import Avatar, AvatarConfig
from loosefit.data.format import write_sequence
from loosefit.fitting.place import fit_skirt
from loosefit.garment.quality import quality
from loosefit.sequence import GarmentSequence
from loosefit.sim.driver import simulate
from loosefit.sim.jobs import job_motion, plan_jobs
from loosefit.sim.presets import preset


def _assignments(items: list[str], flag: str) -> dict[str, float]:
    """FIELD=VALUE arguments as {field: number}."""
    out = {}
    for item in items:
        field, sep, value = item.partition("=")
        if not sep:
            raise SystemExit(f"{flag}: expected FIELD=VALUE, found {item!r}")
        out[field] = float(value)
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("windows", nargs="+", help="JOB:START:STOP of the preset's jobs")
    p.add_argument("--preset", default="salsa", help="salsa, dance, ... (its jobs and cloth)")
    p.add_argument("--bvh", default="../shared/mocap/cmu-salsa")
    p.add_argument(
        "--arms",
        default="true",
        choices=("true", "false", "upper", "preset"),
        help="the body collider's arms (preset: the preset's collider as it is)",
    )
    p.add_argument(
        "--set",
        nargs="*",
        default=[],
        metavar="FIELD=VALUE",
        help="ClothConfig fields to change (numbers), e.g. overlap_inset=-0.01",
    )
    p.add_argument(
        "--unfold",
        nargs="*",
        default=[],
        metavar="FIELD=VALUE",
        help="UnfoldConfig fields to change (numbers), e.g. max_degrees=25",
    )
    p.add_argument(
        "--save",
        default=None,
        help="write each window's sequence to SAVE_JOB_START_STOP.npz (loosefit render, "
        "diagnose and export read it)",
    )
    args = p.parse_args()
    changes, unfold = _assignments(args.set, "--set"), _assignments(args.unfold, "--unfold")
    torch.set_num_threads(1)
    config = preset(args.preset, args.bvh)
    config.unfold = dataclasses.replace(config.unfold, **unfold)
    arms = {"true": True, "false": False, "upper": "upper", "preset": config.cloth.arm_collision}[
        args.arms
    ]
    jobs = {j.name: j for j in plan_jobs(config)}
    avatar = Avatar(AvatarConfig(shape=dict(config.shape)))
    template = fit_skirt(avatar, config.garment)
    for window in args.windows:
        name, start, stop = window.rsplit(":", 2)
        if name not in jobs:
            raise SystemExit(f"{window}: expected a job among {sorted(jobs)}")
        job = jobs[name]
        # the pose correction sees the collider being tried (its arms among the limbs)
        cloth = dataclasses.replace(config.cloth, seed=job.seed, arm_collision=arms, **changes)
        motion = job_motion(dataclasses.replace(config, cloth=cloth), job, avatar)
        motion = motion.slice(int(start), int(stop))
        t0 = time.perf_counter()
        result = simulate(avatar, template, motion, cloth)
        body = avatar.pose_motion(motion).vertices.numpy()
        g = result.garment_vertices
        q = quality(g, template, body, avatar.collider_faces(arms=True).numpy())
        figures = {k: round(float(v), 4) for k, v in q.items() if np.isscalar(v)}
        # the whole body as two closed meshes that never overlap themselves, the trunk with
        # legs and head (arms cut) and the arms: one mesh's closest face misjudges cloth
        # where a forearm lies pressed into the hip
        two = quality(
            g,
            template,
            body,
            (avatar.collider_faces(arms=False).numpy(), avatar.cut_limb_faces(False).numpy()),
        )
        figures["two_mesh_deepest"] = round(two["inside_depth_max"], 4)
        figures["two_mesh_frames_over_5mm"] = int((two["penetration_fraction"] > 0).sum())
        if args.save:  # a sequence that loosefit render / diagnose / export read
            write_sequence(
                Path(f"{args.save}_{name}_{start}_{stop}.npz"),
                GarmentSequence(
                    dataclasses.replace(motion, name=name),
                    template,
                    g,
                    {"rig": avatar.config.rig, "shape": dict(avatar.shape)},
                    "newton-vbd",
                ),
            )
        figures["released_frames"] = result.stats.get("released_frames", 0)
        figures["released_vertices"] = result.stats.get("released_vertices", 0)
        figures["seconds"] = round(time.perf_counter() - t0, 1)
        figures.update({k: v for k, v in motion.meta.get("unfold", {}).items() if np.isscalar(v)})
        print(
            window,
            f"arm_collision={args.arms}",
            " ".join(args.set + args.unfold),
            json.dumps(figures),
            flush=True,
        )


if __name__ == "__main__":
    main()
