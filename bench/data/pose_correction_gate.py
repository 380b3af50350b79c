"""Does a clip pass the data set's quality gate without its pose correction?

Usage:
    OMP_NUM_THREADS=1 .venv/bin/python bench/data/pose_correction_gate.py [--clip 60_04]
        [--frames 40] [--preset dance]

Simulates the clip's first ``--frames`` frames twice, with the preset's cloth: the motion
as loaded, and pose-corrected as the data set's worker corrects it; prints what the gate
says of each. (Why a GPU table that skipped the correction flagged clips that a data set
keeps.)
"""

from __future__ import annotations

import argparse
import dataclasses

import torch

from loosefit.sim.driver import simulate_batch
from loosefit.sim.jobs import job_motion, plan_jobs
from loosefit.sim.manifest import clip_entry
from loosefit.sim.presets import preset
from loosefit.sim.workers import Worker


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--preset", default="dance")
    p.add_argument("--clip", default="60_04")
    p.add_argument("--frames", type=int, default=40)
    args = p.parse_args()
    torch.set_num_threads(1)
    config = preset(args.preset)
    worker = Worker.build(config)
    job = {j.name: j for j in plan_jobs(config)}[args.clip]
    raw = job_motion(config, job, worker.avatar, unfold=False).slice(0, args.frames)
    short = dataclasses.replace(config.motions, max_frames=args.frames)
    fixed = job_motion(dataclasses.replace(config, motions=short), job, worker.avatar)
    for name, motion in (("as loaded", raw), ("pose-corrected", fixed)):
        (result,) = simulate_batch(
            worker.avatar, worker.template, [motion], config.cloth, seeds=[job.seed]
        )
        entry = clip_entry(config, job, motion, result)
        print(f"{args.clip}, {name}: {entry['status']} {entry.get('reason', '')}", flush=True)


if __name__ == "__main__":
    main()
