"""Where the raised knee comes through the skirt: after the motion stage or after collision?

On the clips of a data set (the validation clips by default, never the held-out ones), at
every frame with a knee raised 10 cm above the other: whether the cloth lies in front of the
raised knee (:func:`loosefit.eval.ensemble.cloth_in_front`) in the simulation and in the
shipped set's garment, after the motion stage alone and after every stage, and with collision
handling's sticky side (``CollisionConfig.sticky_factor``) at other values. *Missed*: frames
the simulation covers and the model does not. Writes the section "The raised knee" of
``--page``::

    OMP_NUM_THREADS=1 python bench/quality/knee_cover.py --data datasets/dance --feedback \\
        --page docs/design/notes/collision.md
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

import loosefit
from loosefit.api.options import stages
from loosefit.data.format import DatasetReader
from loosefit.eval.ensemble import clip_context, knee_cover
from loosefit.eval.heldout import validation_clips
from loosefit.eval.metrics import rmse_per_frame
from loosefit.eval.report import write_section
from loosefit.inference.stages.collision import CollisionConfig
from loosefit.train.common import machine


def variants(
    factors: list[float], feedback: bool = False
) -> list[tuple[str, object, CollisionConfig | None]]:
    """(label, stages, collision config) of each garment scored; ``feedback`` adds every
    stage at the default sticky factor with its garment fed back as the next frame's
    previous state."""
    motion_only = stages(detail=False, lengths=False, collision=False)
    out = [("motion stage alone", motion_only, None)]
    default = CollisionConfig().sticky_factor
    for f in factors:
        label = f"every stage, sticky factor {f:g}" + (" (default)" if f == default else "")
        out.append((label, stages(), replace(CollisionConfig(), sticky_factor=f)))
    if feedback:
        out.append(("every stage, fed back", stages(feedback=True), None))
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--checkpoint", default=None, help="a set or checkpoint (the pretrained set)")
    p.add_argument("--data", default="datasets/dance")
    p.add_argument("--clips", default="validation", help="validation, or a split's name")
    p.add_argument("--factors", default="1.5,3,100", help="sticky factors tried")
    p.add_argument(
        "--feedback", action="store_true", help="also every stage with its garment fed back"
    )
    p.add_argument("--page", default=None, help="a Markdown page to write the section into")
    p.add_argument("--json", default=None, help="also the rows and totals as JSON here")
    args = p.parse_args()
    torch.set_num_threads(1)
    started = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    reader = DatasetReader(args.data)
    clips = validation_clips(reader) if args.clips == "validation" else reader.split(args.clips)
    animator = loosefit.load(args.checkpoint)
    model = animator.model
    avatar = model.avatar()
    tried = variants([float(x) for x in args.factors.split(",") if x], args.feedback)
    rows, totals = [], {label: [0, 0] for label, _, _ in tried}
    for name in clips:
        seq = reader.read(name)
        ctx = clip_context(seq, seq.num_frames, avatar)
        if not ctx.knee_frames:
            continue
        truth = seq.garment_vertices
        sim = knee_cover(truth[None], ctx)[0]
        for label, which, collision in tried:
            with model.configured(collision=collision):
                g = animator.animate(seq.motion, stages=which, threads=1).vertices
            ours = knee_cover(g[None], ctx)[0]
            missed = int(np.sum(sim & ~ours))
            k = ctx.knee_frames
            rmse = 100 * float(np.sqrt(np.mean(rmse_per_frame(g[k], truth[k]) ** 2)))
            rows.append((name, len(k), int(sim.sum()), label, int(ours.sum()), missed, rmse))
            totals[label][0] += missed
            totals[label][1] += int(sim.sum())
            print(f"{name} {label}: covers {int(ours.sum())}, missed {missed}", flush=True)
    lines = [
        "# The raised knee",
        "",
        f"Made by `bench/quality/knee_cover.py` on `{args.data}` ({args.clips} clips), "
        f"{machine('cpu')}, {started}. At each frame with a knee raised 10 cm above the "
        "other: the frames whose cloth lies in front of the raised knee, in the simulation "
        "and in the set's garment; *missed*: covered in the simulation, not in ours; RMSE "
        "over those frames.",
        "",
        "| clip | raised-knee frames | simulation covers | garment | ours covers | missed "
        "| RMSE there cm |",
        "|---|---:|---:|---|---:|---:|---:|",
    ]
    lines += [
        f"| `{c}` | {k} | {sim} | {label} | {ours} | {missed} | {rmse:.2f} |"
        for c, k, sim, label, ours, missed, rmse in rows
    ]
    lines += ["", "Missed over all clips, of the frames the simulation covers:", ""]
    lines += [f"- {label}: {m} of {s}" for label, (m, s) in totals.items()]
    page = "\n".join(lines) + "\n"
    print(page)
    if args.page:
        write_section(args.page, "## The raised knee", page)
    if args.json:
        keys = ("clip", "knee_frames", "simulation_covers", "garment", "ours_covers", "missed")
        record = {
            "checkpoint": args.checkpoint,
            "data": args.data,
            "clips": args.clips,
            "started": started,
            "rows": [dict(zip(keys + ("rmse_cm",), row, strict=True)) for row in rows],
            "totals": {
                label: {"missed": m, "simulation_covers": s} for label, (m, s) in totals.items()
            },
        }
        Path(args.json).write_text(json.dumps(record, indent=1) + "\n")


if __name__ == "__main__":
    main()
