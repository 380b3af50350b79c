"""Pictures of the stages: simulation | today | after, on chosen frames of simulated clips.

For one clip of a data set (or a simulated sequence ``.npz``), the clip's motion is animated
twice: as the pipeline ran before the arms joined collision handling (``today``: the
``--before`` set, by default the committed one, with detail, then collision handling without
the arms and without the last projection) and as it runs now (``after``: the committed set
with detail, edge lengths, collision handling against the whole body). The chosen frames are
rendered next to the simulation, one row a frame, each from the front and the
side, the whole body (arms and hands) drawn, and tiled into one picture::

    .venv/bin/python bench/quality/stage_renders.py --data datasets/account --clip spin \\
        --frames 15,45,75 --out docs/img/stage_spin.jpg
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image

import loosefit
from loosefit.inference.stages import Stages
from loosefit.inference.stages.collision import CollisionConfig
from loosefit.render.renderer import RenderConfig
from loosefit.render.video import comparison_sheet

TODAY = CollisionConfig(finish=0, whole_body=False)  # no arms, no last projection


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--checkpoint", default="checkpoints/salsa/motion.pt")
    p.add_argument(
        "--before",
        default=None,
        help="the set of the 'today' column (default: --checkpoint's), e.g. "
        "out/salsa-without-physics-terms/motion.pt",
    )
    p.add_argument("--data", default="datasets/account", help="a data set folder")
    p.add_argument("--clip", default=None, help="the clip (default: the first)")
    p.add_argument("--sequence", default=None, help="a simulated sequence .npz instead")
    p.add_argument("--frames", required=True, help="comma-separated frames of the clip")
    p.add_argument("--views", default="front,side")
    p.add_argument("--size", type=int, default=300, help="pixels per view")
    p.add_argument("--out", required=True)
    args = p.parse_args()

    from loosefit.data.format import DatasetReader, read_any_sequence

    if args.sequence:
        seq = read_any_sequence(args.sequence)
    else:
        reader = DatasetReader(args.data, allow_incomplete=True)
        names = sorted(f.stem for f in (Path(args.data) / "sequences").glob("*.npz"))
        seq = reader.read(args.clip or names[0])
    picks = [int(f) for f in args.frames.split(",")]
    model = loosefit.load(args.checkpoint).model
    after = model.animate(seq.motion, stages=Stages()).vertices
    before = loosefit.load(args.before).model if args.before else model
    with before.configured(collision=TODAY):
        today = before.animate(seq.motion, stages=Stages(lengths=False)).vertices
    avatar = model.avatar()
    body = avatar.pose_motion(seq.motion).vertices.cpu().numpy()[picks]
    columns = {
        "simulation": np.asarray(seq.garment_vertices)[picks],
        "today": today[picks],
        "after": after[picks],
    }
    config = RenderConfig(
        width=args.size,
        height=args.size,
        views=tuple(args.views.split(",")),
        follow=True,
        frame_counter=False,
    )
    sheet = comparison_sheet(
        columns, picks, body, avatar.faces.cpu().numpy(), model.template.faces, config
    )
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(sheet).save(out, quality=85)
    print(f"wrote {out} ({sheet.shape[1]}x{sheet.shape[0]})")


if __name__ == "__main__":
    main()
