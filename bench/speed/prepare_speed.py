"""How long a batched data set run takes to prepare its clips' motions (loaded, pose-corrected)
before the first batch: in one process, as a worker used to for each of its batch's clips in
turn, and in several at once, as ``loosefit simulate --batch`` now does.

Usage:
    .venv/bin/python bench/speed/prepare_speed.py [--preset dance] [--clips 05_02,05_10,05_12,05_20]
        [--processes 1,2] [--out docs/results/SIM_SPEED.md]

Each run prepares the same clips (``workers.prepare_motions``, longest first) and is timed
from the call to the last motion, the processes' start (imports, the avatar) included. The
motions of every run are checked to be those of the first, to the bit.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from datetime import date

import numpy as np

SECTION = "## Preparing motions on every core"  # of docs/results/SIM_SPEED.md


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--preset", default="dance")
    p.add_argument("--bvh", default=None, help="the salsa folder (dance: cmu-ballet beside it)")
    p.add_argument("--clips", default="05_02,05_10,05_12,05_20", help="clip names; '' for all")
    p.add_argument("--processes", default="1,2", help="comma-separated process counts")
    p.add_argument(
        "--out",
        default="",
        help=f"a Markdown page (docs/results/SIM_SPEED.md) whose section '{SECTION}' the tables "
        "replace, the rest of the page kept",
    )
    args = p.parse_args(argv)

    from loosefit.sim.jobs import job_motion, plan_jobs
    from loosefit.sim.presets import preset
    from loosefit.sim.workers import prepare_motions

    config = preset(args.preset, args.bvh)
    jobs = {j.name: j for j in plan_jobs(config)}
    names = [n for n in args.clips.split(",") if n] or list(jobs)
    missing = [n for n in names if n not in jobs]
    if missing:
        raise SystemExit(f"no clip {', '.join(missing)} in the preset (it has {', '.join(jobs)})")

    from loosefit.body.avatar import Avatar, AvatarConfig

    avatar = Avatar(AvatarConfig(shape=dict(config.shape)))
    frames = {n: job_motion(config, jobs[n], avatar, unfold=False).num_frames for n in names}
    order = sorted(names, key=lambda n: -frames[n])
    rows, first = [], None
    for processes in (int(x) for x in args.processes.split(",")):
        t0 = time.perf_counter()
        motions = prepare_motions(config, [jobs[n] for n in order], processes)
        seconds = time.perf_counter() - t0
        if first is None:
            first = motions
        same = all(
            np.array_equal(a.rotations, b.rotations) for a, b in zip(first, motions, strict=True)
        )
        rows.append((processes, seconds, same))
        print(f"{processes} processes: {seconds:.1f} s (the same motions: {same})", flush=True)
    total = sum(frames.values())
    base = rows[0][1]
    command = " ".join(argv if argv is not None else os.sys.argv[1:])
    listed = ", ".join(f"{n} ({frames[n]})" for n in order)
    text = "\n".join(
        [
            "# Preparing a batched run's motions",
            "",
            f"`python bench/speed/prepare_speed.py {command}`; "
            f"{platform.node()}, {platform.processor() or platform.machine()}, "
            f"{os.cpu_count()} cores; {date.today()}.",
            "",
            f"{len(order)} clips of `{config.preset}` ({listed}; "
            f"{total} frames), loaded and pose-corrected.",
            "",
            "| processes | s | s a frame | speed-up | the same motions |",
            "|---:|---:|---:|---:|---|",
            *(
                f"| {n} | {s:.1f} | {s / total:.3f} | {base / s:.2f}x | {'yes' if same else 'NO'} |"
                for n, s, same in rows
            ),
        ]
    )
    print(text)
    if args.out:
        from loosefit.eval.report import write_section

        write_section(args.out, SECTION, text + "\n")


if __name__ == "__main__":
    main()
