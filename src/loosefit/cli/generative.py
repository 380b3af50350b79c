"""``loosefit reconstruct`` and ``loosefit interpolate``: look at what a trained generative
model (the garment VAE) has learnt."""

from __future__ import annotations

import argparse
from pathlib import Path

from loosefit.cli.common import add_avatar_args, add_render_args, log, render, stored_clip
from loosefit.errors import LoosefitInputError


def add_reconstruct_parser(sub) -> None:
    p = sub.add_parser("reconstruct", help="encode and decode a clip with a generative model")
    p.add_argument("--checkpoint", required=True, help="a generative run's checkpoint.pt")
    p.add_argument("--data", default="datasets/demo", help="a dataset folder")
    p.add_argument("--clip", default=None, help="the clip (default: the first test clip)")
    p.add_argument("--max-frames", type=int, default=None)
    p.add_argument("--out", default="out/reconstruct")
    add_avatar_args(p)
    add_render_args(p, views="front,side")
    p.set_defaults(func=run_reconstruct)


def add_interpolate_parser(sub) -> None:
    p = sub.add_parser("interpolate", help="garments along a line between two latent codes")
    p.add_argument("--checkpoint", required=True, help="a generative run's checkpoint.pt")
    p.add_argument("--data", default="datasets/demo", help="the dataset holding the two frames")
    p.add_argument("--a", required=True, help="CLIP:FRAME of the first garment")
    p.add_argument("--b", required=True, help="CLIP:FRAME of the second garment")
    p.add_argument("--steps", type=int, default=8)
    p.add_argument("--out", default="out/interpolation")
    p.add_argument("--size", type=int, default=384)
    p.set_defaults(func=run_interpolate)


def run_reconstruct(args: argparse.Namespace) -> int:
    from loosefit.api.generative import open_generative

    gen = open_generative(args.checkpoint, args.data)
    name = args.clip or gen.split("test")[0]
    seq = gen.read(name)
    avatar, motion, garment = stored_clip(
        args, gen.body.get("shape", {}), seq.motion, seq.garment_vertices
    )
    rec = gen.reconstruct(motion, garment)
    world = rec.sequence.garment_vertices
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rec.sequence.save(out / "reconstruction.npz")
    log(
        f"{name}: {len(world)} frames, RMSE {100 * rec.rmse:.2f} cm; wrote "
        f"{out / 'reconstruction.npz'} (a sequence, as render --sequence reads)"
    )
    title = f"{name}: generative reconstruction"
    render(args, avatar, motion, gen.template, world, out, title=title)
    return 0


def _frame_ref(text: str, names: list[str], source: str) -> tuple[str, int]:
    """``--a``/``--b`` ``CLIP:FRAME`` as (clip, frame)."""
    name, _, frame = text.rpartition(":")
    if not name or not frame.isdigit():
        raise LoosefitInputError(source, "frame", "CLIP:FRAME, e.g. 'dance_000:40'", repr(text))
    if name not in names:
        raise LoosefitInputError(source, "clip", f"one of {names}", repr(name))
    return name, int(frame)


def run_interpolate(args: argparse.Namespace) -> int:
    from loosefit.api.generative import open_generative, render_interpolation

    gen = open_generative(args.checkpoint, args.data)
    ends = []
    for which, text in (("--a", args.a), ("--b", args.b)):
        name, f = _frame_ref(text, gen.split("all"), which)
        seq = gen.read(name)
        if not 0 <= f < seq.num_frames:
            raise LoosefitInputError(
                which, "frame", f"a frame of '{name}' (0..{seq.num_frames - 1})", f
            )
        ends.append((seq, f))
    line = gen.interpolate(*ends, steps=args.steps)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    line.save(out / "interpolation.npz")
    log(f"wrote {out / 'interpolation.npz'} ({args.steps} garments, root frame)")
    title = f"latent interpolation {args.a} -> {args.b}"
    result = render_interpolation(line, out, title=title, size=args.size)
    log(f"wrote {result.video}" + (f" and {result.sheet}" if result.sheet else ""))
    return 0
