"""A picture of the engine tier beside the full pipeline on the demo's dance.

The demo's motion (``loosefit demo``: ``dance:20``, seed 0) is animated by the full pipeline
(``animate``: every stage) and by the engine tier (its PyTorch rollout with the capsule
push-out, as the exported graph runs it; ``--before``: also another engine.pt, pushed out as
before, the waistband too). The chosen frames are rendered one row a frame, from the front
and the back, the body drawn, and tiled into one compressed JPEG::

    python bench/quality/engine_renders.py --frames 60,240,420 --out docs/img/engine_demo.jpg
"""

from __future__ import annotations

import argparse
from pathlib import Path

from PIL import Image

import loosefit
from loosefit.api import pretrained_checkpoint
from loosefit.body.capsules import avatar_capsules
from loosefit.inference.engine.export import EngineStep, skeleton_record
from loosefit.inference.engine.model import engine_path_of, load_engine, rollout_engine
from loosefit.motion.motions import load_motion
from loosefit.render.renderer import RenderConfig
from loosefit.render.video import comparison_sheet


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--checkpoint", default=None, help="motion.pt (default: the pretrained)")
    p.add_argument("--engine", default=None, help="engine.pt (default: beside --checkpoint)")
    p.add_argument("--before", default=None, help="another engine.pt, pushed out as before")
    p.add_argument("--motion", default="dance:20")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--frames", default="60,240,420", help="comma-separated motion frames")
    p.add_argument("--views", default="front,back")
    p.add_argument("--size", type=int, default=260, help="pixels per view")
    p.add_argument("--quality", type=int, default=80, help="JPEG quality")
    p.add_argument("--out", default="docs/img/engine_demo.jpg")
    args = p.parse_args()
    checkpoint = Path(args.checkpoint) if args.checkpoint else pretrained_checkpoint()
    model = loosefit.load(checkpoint).model
    avatar = model.avatar()
    engine = load_engine(args.engine or engine_path_of(checkpoint))
    motion = load_motion(args.motion, avatar, fps=engine.fps, seed=args.seed)
    picks = [int(f) for f in args.frames.split(",")]
    capsules, skeleton = avatar_capsules(avatar), skeleton_record(avatar)
    columns = {"full pipeline": model.animate(motion).vertices[picks]}
    if args.before:
        before = load_engine(args.before)
        step = EngineStep(before, capsules, skeleton, waist_blend=0).eval()
        columns["engine tier, before"] = rollout_engine(before, motion, collide=step)[picks]
    step = EngineStep(engine, capsules, skeleton).eval()
    columns["engine tier"] = rollout_engine(engine, motion, collide=step)[picks]
    body = avatar.pose_motion(motion).vertices.cpu().numpy()[picks]
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
    Image.fromarray(sheet).save(out, quality=args.quality, optimize=True)
    print(f"wrote {out} ({sheet.shape[1]}x{sheet.shape[0]}, {out.stat().st_size // 1024} KB)")


if __name__ == "__main__":
    main()
