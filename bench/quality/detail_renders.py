"""Pictures of the held-out chain's fastest spin: simulation | motion stage alone | full pipeline.

The salsa data's held-out chain (60_03 + 60_07 + 61_03 + 61_07, never seen in training)
is rolled out from its first frame by the committed model twice: the motion stage
alone (the decoders' garment, what the model gave before detail enhancement and
collision handling) and the whole pipeline (detail, then collision handling). The
frames of the spin (1,188-1,208 by default, as in docs/use/DATASET.md) are rendered
next to the simulation, one row a frame, columns simulation | before | after, each
from the front and the side, and tiled into one picture::

    python bench/quality/detail_renders.py --data datasets/salsa --out docs/img/detail_spin.jpg

A hip close-up (``--close``) frames only the waist and hips, where the body showed
through the skirt.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from PIL import Image

import loosefit
from loosefit.data.format import DatasetReader
from loosefit.inference.animator import attach_detail
from loosefit.inference.stages import MOTION_ONLY, Stages
from loosefit.render.camera import CameraView
from loosefit.render.renderer import RenderConfig
from loosefit.render.video import comparison_sheet


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--checkpoint", default="checkpoints/salsa/motion.pt")
    p.add_argument(
        "--detail",
        default=None,
        help="a detail run's model.pt (default: the detail.pt packaged beside)",
    )
    p.add_argument("--data", default="datasets/salsa")
    p.add_argument("--frames", default="1188:1209:4", help="start:stop:step of the chain")
    p.add_argument("--size", type=int, default=360, help="pixels per view")
    p.add_argument("--close", action="store_true", help="frame the hips only")
    p.add_argument("--out", default="docs/img/detail_spin.jpg")
    args = p.parse_args()

    reader = DatasetReader(args.data)
    name = next(n for n in reader.split("test") if n.startswith("chain_"))
    seq = reader.read(name)
    model = loosefit.load(args.checkpoint).model
    if args.detail:
        attach_detail(model, args.detail)
    if model.detail is None:
        raise SystemExit(f"{args.checkpoint}: no detail stage packaged beside it")
    start, stop, step = (int(x) for x in args.frames.split(":"))
    picks = list(range(start, min(stop, seq.motion.num_frames), step))
    before = model.animate(seq.motion, stages=MOTION_ONLY).vertices
    after = model.animate(seq.motion, stages=Stages()).vertices
    avatar = model.avatar()
    body = avatar.pose_motion(seq.motion).vertices.cpu().numpy()[picks]
    body_faces = avatar.faces.cpu().numpy()
    columns = {
        "simulation": seq.garment_vertices[picks],
        "before (motion stage)": before[picks],
        "after (detail + collision)": after[picks],
    }
    if args.close:
        views = (
            CameraView("front", 0.0, 8.0, distance=1.1),
            CameraView("side", 90.0, 8.0, distance=1.1),
        )
    else:
        views = ("front", "side")
    config = RenderConfig(
        width=args.size, height=args.size, views=views, follow=True, frame_counter=False
    )
    sheet = comparison_sheet(columns, picks, body, body_faces, model.template.faces, config)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(sheet).save(out, quality=88)
    print(f"wrote {out} ({sheet.shape[1]}x{sheet.shape[0]})")


if __name__ == "__main__":
    main()
