"""``loosefit motion`` (a motion capture file or a procedural move to a motion .npz) and
``loosefit inspect-motion`` (how a motion capture file would be read)."""

from __future__ import annotations

import argparse
from pathlib import Path

from loosefit.cli.common import (
    add_avatar_args,
    add_bvh_args,
    build_avatar,
    log,
    retarget_config,
)
from loosefit.errors import LoosefitInputError


def add_motion_parser(sub) -> None:
    p = sub.add_parser(
        "motion",
        help="convert a BVH, glTF or SMPL file or a procedural move to a motion .npz",
    )
    p.add_argument(
        "spec",
        help="a .bvh, .gltf/.glb or SMPL .npz file, a procedural move name, or dance:SECONDS",
    )
    p.add_argument("--out", required=True, help="output .npz")
    p.add_argument("--fps", type=float, default=30.0)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--max-frames", type=int, default=None)
    add_bvh_args(p)
    add_avatar_args(p)
    p.set_defaults(func=run_motion)


def add_inspect_parser(sub) -> None:
    p = sub.add_parser(
        "inspect-motion",
        help="how a motion capture file (BVH, glTF, SMPL .npz) would be read: its joints, "
        "the avatar joint each drives and why, the dancer's height, units, frames",
    )
    p.add_argument("file", help="a .bvh, .gltf/.glb or SMPL .npz file")
    add_bvh_args(p)
    p.add_argument(
        "--sheet",
        metavar="PNG",
        default=None,
        help="also retarget it onto the avatar, run the pose check, and write a "
        "contact sheet: the capture's skeleton (sticks) beside the avatar at a few "
        "frames",
    )
    p.add_argument("--sheet-frames", type=int, default=6, help="frames on the --sheet")
    p.add_argument(
        "--write-joint-map",
        metavar="YAML",
        default=None,
        help="write a joint map file filled in with what was matched (or, when "
        "nothing could be, guessed by name), to correct and pass as --joint-map",
    )
    add_avatar_args(p)
    p.set_defaults(func=run_inspect)


def run_motion(args: argparse.Namespace) -> int:
    from loosefit.motion.motions import load_motion

    avatar = build_avatar(args)
    motion = load_motion(
        args.spec,
        avatar,
        fps=args.fps,
        seed=args.seed,
        retarget=retarget_config(args),
        max_frames=args.max_frames,
    )
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    motion.save(out)
    log(f"wrote {out}: {motion.num_frames} frames at {motion.fps:g} fps, {motion.duration:.1f} s")
    return 0


def run_inspect(args: argparse.Namespace) -> int:
    from loosefit.motion.inspect import inspect_motion
    from loosefit.motion.joint_map_files import joint_map_template

    config = retarget_config(args)
    report = inspect_motion(args.file, config)
    print(report.format())
    if args.write_joint_map:
        out = Path(args.write_joint_map)
        axes = (report.up, report.forward)
        out.write_text(
            joint_map_template(
                report.clip.joint_names, report.match, str(args.file), axes, report.clip.parents
            )
        )
        log(f"wrote {out}: correct it and pass --joint-map {out}")
    if report.error is not None:
        raise report.error
    if args.sheet:
        _motion_sheet(args, report.clip, config)
    return 0


def _motion_sheet(args: argparse.Namespace, clip, config) -> None:
    """inspect-motion --sheet: retarget at the file's rate, check the poses, draw the sheet."""
    import dataclasses

    from PIL import Image

    from loosefit.motion.inspect import sheet_inputs
    from loosefit.motion.pose_check import check_pose
    from loosefit.motion.retarget import retarget_bvh
    from loosefit.render.skeleton_sheet import skeleton_sheet

    avatar = build_avatar(args)
    # drawn whatever the checks say: the sheet is how to see why they fail
    loose = dataclasses.replace(config, fps=None, check_pose=False, check_height=False)
    motion = retarget_bvh(clip, avatar.skeleton, avatar.floor_height, loose)
    refusal = None
    try:
        check_pose(motion, avatar.skeleton, avatar.floor_height, str(args.file))
        print("pose check: passes (standing, feet on the floor, no joint too fast)")
    except LoosefitInputError as exc:
        print(f"pose check: fails: {exc.found}")
        refusal = exc if config.check_pose else None
    sheet = sheet_inputs(clip, motion, loose, args.sheet_frames)
    body = avatar.pose_motion(sheet.motion).vertices.cpu().numpy()
    faces = avatar.faces.cpu().numpy()
    image = skeleton_sheet(sheet.points, sheet.bones, body, faces, sheet.frames)
    out = Path(args.sheet)
    out.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(image).save(out)
    log(f"wrote {out}: the capture's skeleton (left) beside the avatar, frames {sheet.frames}")
    if refusal is not None:
        raise refusal
