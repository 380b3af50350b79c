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
    import torch

    from loosefit.data.format import DatasetReader
    from loosefit.eval.metrics import rmse
    from loosefit.inference.checkpoints import load_generative
    from loosefit.model.motion_features import (
        from_root_frame,
        garment_in_root_frame,
        motion_root_frames_of,
    )
    from loosefit.sequence import GarmentSequence

    reader = DatasetReader(args.data)
    model, _ = load_generative(args.checkpoint, reader.template)
    name = args.clip or reader.split("test")[0]
    seq = reader.read(name)
    avatar, motion, garment = stored_clip(
        args, reader.body.get("shape", {}), seq.motion, seq.garment_vertices
    )
    H, p = motion_root_frames_of(motion)
    with torch.no_grad():
        rec = model.reconstruct_all(garment_in_root_frame(motion, garment), 64)
        world = from_root_frame(rec, H, p).numpy()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    source = f"generative reconstruction {Path(args.checkpoint).resolve()}"
    GarmentSequence(motion, reader.template, world, reader.avatar, source).save(
        out / "reconstruction.npz"
    )
    log(
        f"{name}: {len(world)} frames, RMSE {100 * rmse(world, garment):.2f} cm; wrote "
        f"{out / 'reconstruction.npz'} (a sequence, as render --sequence reads)"
    )
    title = f"{name}: generative reconstruction"
    render(args, avatar, motion, reader.template, world, out, title=title)
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
    import numpy as np
    import torch

    from loosefit.data.format import DatasetReader
    from loosefit.inference.checkpoints import load_generative
    from loosefit.model.motion_features import garment_in_root_frame
    from loosefit.render.clip import render_clip
    from loosefit.render.renderer import RenderConfig, RenderMesh

    reader = DatasetReader(args.data)
    model, _ = load_generative(args.checkpoint, reader.template)
    posed = []
    for which, text in (("--a", args.a), ("--b", args.b)):
        name, f = _frame_ref(text, reader.split("all"), which)
        seq = reader.read(name)
        if not 0 <= f < seq.num_frames:
            raise LoosefitInputError(
                which, "frame", f"a frame of '{name}' (0..{seq.num_frames - 1})", f
            )
        posed.append(
            garment_in_root_frame(seq.motion.slice(f, f + 1), seq.garment_vertices[f : f + 1])
        )
    with torch.no_grad():
        mu, _ = model.encode(torch.cat(posed))
        alpha = torch.linspace(0, 1, args.steps)[:, None]
        garments = model.decode((1 - alpha) * mu[0] + alpha * mu[1])["vertices"].numpy()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    np.savez(
        out / "interpolation.npz",
        vertices=garments,
        faces=reader.template.faces,
        alpha=alpha[:, 0].numpy(),
    )
    log(f"wrote {out / 'interpolation.npz'} ({args.steps} garments, root frame)")
    # root frame -> standing on the floor, root joint at its rest height
    lifted = garments + np.array([0.0, 0.0, float(reader.body.get("floor_height", 0.9))])
    scene = [RenderMesh(reader.template.faces, lifted, "garment", name="garment")]
    config = RenderConfig(width=args.size, height=args.size, views=("front", "side"), follow=False)
    result = render_clip(
        scene,
        out,
        fps=4.0,
        config=config,
        png_every=1,
        title=f"latent interpolation {args.a} -> {args.b}",
    )
    log(f"wrote {result.video}" + (f" and {result.sheet}" if result.sheet else ""))
    return 0
