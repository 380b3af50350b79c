"""A picture of bench/data/sim_quality.py's runs: the preset's cloth beside a candidate's, at a
few frames of a clip, front and side.

Usage:
    .venv/bin/python bench/data/sim_quality_sheet.py --clip 05_10 --frames 60,110
        --candidate NAME:KEY=VALUE,... [--cache out/sim_quality] [--out sheet.jpg]

Reads the runs from ``--cache`` (bench/data/sim_quality.py's, same clip and ``--motion-frames``),
simulating any that are missing as that script does. One row a frame: the preset's run,
then each candidate's.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch
from PIL import Image

from loosefit.eval.sim_runs import candidate_config, parse_candidate, simulate_run


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--preset", default="dance")
    p.add_argument("--clip", default="05_10")
    p.add_argument("--motion-frames", type=int, default=120, help="the runs' --frames")
    p.add_argument("--frames", default="60,110", help="the frames shown")
    p.add_argument("--candidate", action="append", default=[], help="NAME:KEY=VALUE,...")
    p.add_argument("--cache", default="out/sim_quality")
    p.add_argument("--size", type=int, default=360, help="pixels a view, wide")
    p.add_argument("--out", default="out/sim_quality_sheet.jpg")
    args = p.parse_args(argv)

    from loosefit.render.renderer import RenderConfig, Renderer, RenderMesh
    from loosefit.sim.jobs import plan_jobs
    from loosefit.sim.workers import Worker

    config = candidate_config(args.preset, {})
    worker = Worker.build(config)
    job = {j.name: j for j in plan_jobs(config)}[args.clip]
    motion = worker.motion(job).slice(0, args.motion_frames)
    with torch.no_grad():
        posed = worker.avatar.pose(
            torch.from_numpy(motion.rotations), torch.from_numpy(motion.root_translation)
        )
    body = posed.vertices.numpy()
    faces = worker.avatar.faces.numpy()
    garments = {}  # each run's (T, V, 3) cloth, read (or simulated) once
    for name, changes in [("preset", {})] + [parse_candidate(s) for s in args.candidate]:
        run = simulate_run(args.preset, args.clip, args.motion_frames, 0, changes, args.cache)
        if run["garment"] is None:
            raise SystemExit(f"{name}: the run diverged ({run['reason']})")
        garments[name] = run["garment"]
    look = RenderConfig(
        width=args.size,
        height=int(args.size * 7 / 6),
        views=("front", "side"),
        frame_counter=False,
    )
    rows = []
    with Renderer(look) as renderer:
        for f in (int(f) for f in args.frames.split(",")):
            row = []
            for name, garment in garments.items():
                scene = [
                    RenderMesh(faces, body[f], role="body"),
                    RenderMesh(worker.template.faces, garment[f]),
                ]
                title = f"{args.clip} {name}, frame {f}"
                row.append(next(iter(renderer.render_sequence(scene, title=title, frames=[0]))))
            rows.append(np.concatenate(row, axis=1))
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(np.concatenate(rows, axis=0)).save(args.out, quality=88)
    print(args.out)


if __name__ == "__main__":
    main()
