"""Where a simulated frame's time goes: the cloth simulator profiled phase by phase.

Usage:
    OMP_NUM_THREADS=1 .venv/bin/python bench/speed/sim_profile.py [--preset dance]
        [--clips 60_01,05_10] [--frames 20] [--out docs/results/SIM_SPEED.md] [--set KEY=VALUE]
        [--warp KEY=VALUE]

Times the pose correction of each whole clip as the data set's worker runs it, then
simulates the first ``--frames`` motion frames of the clip exactly as that worker would
(the preset's garment, cloth configuration, pose correction; the settle and
blend frames before them), with every phase of a frame timed: the body's timeline (anny
posing the clip), the body's posing and BVH refit inside each substep, the waistband,
detection of contacts with the body, the solver's parts (forward step, self-contact
detection, the VBD iterations, the rest), the self-contact BVH rebuild once a frame, the
release of trapped cloth and the recording of each frame. Warp's CPU kernels run on the
calling thread, so each launch's wall time is its work: the kernels are timed one by one
too. Graph capture is switched off while profiling (a replayed graph cannot be timed
launch by launch); the seconds per frame with the configuration as it is are printed
beside, from a second run of the same frames.

``--warp KEY=VALUE`` sets one of warp's compiler settings before any kernel is built (e.g.
``--warp optimization_level=3``, ``--warp fast_math=true``): the same solver compiled
otherwise.

``--set KEY=VALUE`` changes the cloth configuration (e.g. ``--set self_contact_passes=1``)
for a quick look at a lever; the quality of such a change is judged by
``bench/data/sim_quality.py``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import time
from datetime import date
from pathlib import Path

import torch
import warp as wp

import loosefit.sim.driver as driver
from loosefit.eval.report import write_section
from loosefit.eval.sim_runs import ONCE, profiled_run
from loosefit.sim.presets import preset
from loosefit.sim.workers import Worker

SECTION = "## Where a frame's time goes"  # of docs/results/SIM_SPEED.md


def profile_clip(worker: Worker, name: str, frames: int, cloth) -> dict:
    """One clip's first ``frames`` motion frames, profiled (capture off) and timed as
    configured."""
    from loosefit.sim.jobs import plan_jobs

    jobs = {j.name: j for j in plan_jobs(worker.config)}
    if name not in jobs:
        raise SystemExit(f"no clip {name} in the preset (it has {', '.join(sorted(jobs))})")
    if worker.parts is None and worker.config.unfold.enabled:  # once a worker, not timed
        from loosefit.sim.jobs import limb_parts

        worker.parts = limb_parts(worker.config, worker.avatar)
    t0 = time.perf_counter()
    whole = worker.motion(jobs[name])  # the pose correction runs over the whole clip
    correction = time.perf_counter() - t0
    motion = whole.slice(0, frames)
    seeds = [jobs[name].seed]
    avatar, template = worker.avatar, worker.template
    profiled, timer, kernels, wall_profiled = profiled_run(avatar, template, motion, cloth, seeds)
    t0, c0 = time.perf_counter(), time.process_time()
    (plain,) = driver.simulate_batch(avatar, template, [motion], cloth, seeds=seeds)
    wall_plain, cpu_plain = time.perf_counter() - t0, time.process_time() - c0
    steps = profiled.preroll_frames + motion.num_frames - 1  # frames stepped
    substeps = plain.stats.get("substeps_mean")
    return {
        "clip": name,
        "motion_frames": motion.num_frames,
        "frames_stepped": steps,
        "substeps_mean": substeps,
        "seconds_per_frame_profiled": wall_profiled / steps,
        "seconds_per_frame": wall_plain / steps,
        "cpu_seconds_per_frame": cpu_plain / steps,  # the process's own: on a shared machine
        "phases": {
            k: {"self": timer.self_[k], "total": timer.total[k], "calls": timer.calls[k]}
            for k in timer.total
        },
        "kernels": {k: {"seconds": v, "calls": kernels.calls[k]} for k, v in kernels.total.items()},
        "quality": {k: plain.quality[k] for k in ("inside_max", "strain_p99", "max_speed")},
        "wall_profiled": wall_profiled,
        "pose_correction": {"seconds": correction, "frames": whole.num_frames},
    }


def markdown(results: list[dict], args, machine: str) -> str:
    lines = [
        "# Where a simulated frame's time goes",
        "",
        f"`{' '.join(['python bench/speed/sim_profile.py', *args])}`; {machine}; {date.today()}.",
        "",
    ]
    for r in results:
        steps = r["frames_stepped"]
        wall = r["wall_profiled"]
        lines += [
            f"## {r['clip']}: {r['motion_frames']} motion frames ({steps} stepped with the "
            f"settle and blend)",
            "",
            f"{r['seconds_per_frame']:.3f} s a frame as configured "
            f"({r['cpu_seconds_per_frame']:.3f} s of the process's CPU time; "
            f"{r['seconds_per_frame_profiled']:.3f} profiled, graph capture off)"
            + (f"; {r['substeps_mean']:.1f} substeps a frame" if r["substeps_mean"] else ""),
            "",
            "Once a clip:",
            "",
            "| phase | s |",
            "|---|---:|",
        ]
        once = set(ONCE.values())
        pc = r["pose_correction"]
        lines.append(
            f"| pose correction of the whole clip ({pc['frames']} frames; the data set's "
            f"worker, before the simulation) | {pc['seconds']:.2f} |"
        )
        for k, v in r["phases"].items():
            if k in once:
                lines.append(f"| {k} | {v['total']:.2f} |")
        looped = {k: v for k, v in r["phases"].items() if k not in once}
        loop = sum(v["self"] for v in looped.values())
        lines += [
            "",
            f"Each frame (the loop over frames: {loop / steps:.3f} s a frame, profiled):",
            "",
            "| phase (exclusive) | s a frame | share of the loop | calls a frame |",
            "|---|---:|---:|---:|",
        ]
        for k, v in sorted(looped.items(), key=lambda kv: -kv[1]["self"]):
            lines.append(
                f"| {k} | {v['self'] / steps:.4f} | {100 * v['self'] / loop:.1f} % | "
                f"{v['calls'] / steps:.1f} |"
            )
        other = wall - sum(v["self"] for v in r["phases"].values())
        lines += [f"| (outside every phase above: {other:.2f} s in all) | | | |", ""]
        lines += [
            "| kernel | s a frame | share of the loop | launches a frame |",
            "|---|---:|---:|---:|",
        ]
        top = sorted(r["kernels"].items(), key=lambda kv: -kv[1]["seconds"])[:15]
        for k, v in top:
            lines.append(
                f"| `{k}` | {v['seconds'] / steps:.4f} | {100 * v['seconds'] / loop:.1f} % | "
                f"{v['calls'] / steps:.0f} |"
            )
        lines.append("")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--preset", default="dance")
    p.add_argument("--clips", default="60_01,05_10", help="clip names of the preset")
    p.add_argument("--frames", type=int, default=20, help="motion frames of each clip")
    p.add_argument("--set", action="append", default=[], help="cloth KEY=VALUE")
    p.add_argument("--warp", action="append", default=[], help="warp.config KEY=VALUE")
    p.add_argument(
        "--out",
        default="",
        help=f"a Markdown page (docs/results/SIM_SPEED.md) whose section '{SECTION}' the tables "
        "replace, the rest of the page kept",
    )
    p.add_argument("--json", default="", help="a JSON file for the figures")
    args = p.parse_args(argv)
    for item in args.warp:  # before the first kernel is built: part of its cache key
        key, _, value = item.partition("=")
        if not hasattr(wp.config, key):
            raise SystemExit(f"--warp {item}: warp.config has no setting {key!r}")
        setattr(wp.config, key, json.loads(value))

    torch.set_num_threads(1)
    config = preset(args.preset)
    changes = {}
    for item in args.set:
        key, _, value = item.partition("=")
        changes[key] = json.loads(value)
    cloth = dataclasses.replace(config.cloth, **changes)
    worker = Worker.build(dataclasses.replace(config, cloth=cloth))
    machine = (
        f"{platform.node()}, {platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} cores, warp {wp.config.version}, one thread"
        + "".join(f", {item}" for item in args.warp)
    )
    results = [profile_clip(worker, c, args.frames, cloth) for c in args.clips.split(",")]
    text = markdown(results, argv if argv is not None else os.sys.argv[1:], machine)
    print(text)
    if args.out:
        write_section(args.out, SECTION, text + "\n")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
