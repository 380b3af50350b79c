"""``loosefit render``: a motion or a saved sequence to MP4 and PNG."""

from __future__ import annotations

import argparse
from pathlib import Path

from loosefit.cli.common import (
    add_avatar_args,
    add_bvh_args,
    add_render_args,
    build_avatar,
    frame_range,
    garment_template,
    log,
    render,
    retarget_config,
    stored_clip,
)
from loosefit.errors import LoosefitInputError


def add_parser(sub) -> None:
    p = sub.add_parser("render", help="render a motion or a saved sequence to MP4 and PNG")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument(
        "--motion",
        help="a .bvh, .gltf/.glb or .npz (loosefit or SMPL) motion, or a procedural move name",
    )
    src.add_argument("--sequence", help="a sequence .npz (animate, the API, demo, a dataset)")
    src.add_argument("--dataset", help="a dataset folder written by loosefit simulate")
    p.add_argument("--clip", default=None, help="with --dataset: the clip (default: the first)")
    p.add_argument(
        "--garment", default="none", help="with --motion: a skirt style, an .obj or none"
    )
    p.add_argument("--out", default="out/render", help="output folder")
    p.add_argument("--start-frame", type=int, default=0, help="first frame to render (0-based)")
    p.add_argument("--max-frames", type=int, default=None, help="render at most this many frames")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--fps", type=float, default=30.0)
    add_bvh_args(p)
    add_avatar_args(p)
    add_render_args(p, views="front,side")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from loosefit.api import motion_for
    from loosefit.api.garment import carry_rigidly
    from loosefit.api.render import read_stored_clip

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    body = None
    if args.sequence or args.dataset:
        stored = read_stored_clip(sequence=args.sequence, dataset=args.dataset, clip=args.clip)
        seq = stored.sequence
        title = f"{stored.label} ({seq.source})"
        avatar, motion, garment = stored_clip(
            args, seq.avatar.get("shape", {}), seq.motion, seq.garment_vertices
        )
        template = seq.garment
    elif args.motion:
        avatar = build_avatar(args)
        motion = motion_for(
            args.motion, avatar, args.fps, seed=args.seed, retarget=retarget_config(args)
        )
        start, stop = frame_range(args, motion.num_frames)
        motion = motion.slice(start, stop)
        template = garment_template(args.garment, avatar)
        garment = None
        if template is not None:
            body = avatar.pose_motion(motion)
            garment = carry_rigidly(template, body, avatar)
        title = motion.name
    else:
        raise LoosefitInputError(
            "loosefit render", "arguments", "--motion, --sequence or --dataset", "none"
        )
    if args.start_frame:
        title += f", from frame {args.start_frame}"
    log(f"rendering {motion.num_frames} frames")
    render(args, avatar, motion, template, garment, out, title=title, body=body)
    return 0
