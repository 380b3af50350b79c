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
    from loosefit.api import motion_for

    avatar = build_avatar(args)
    motion = motion_for(
        args.spec,
        avatar,
        args.fps,
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
    from loosefit.api.motion import inspect_motion, joint_map_text

    config = retarget_config(args)
    report = inspect_motion(args.file, retarget=config)
    print(report.format())
    if args.write_joint_map:
        out = Path(args.write_joint_map)
        out.write_text(joint_map_text(report, str(args.file)))
        log(f"wrote {out}: correct it and pass --joint-map {out}")
    if report.error is not None:
        raise report.error
    if args.sheet:
        _motion_sheet(args, report, config)
    return 0


def _motion_sheet(args: argparse.Namespace, report, config) -> None:
    """inspect-motion --sheet: the capture's skeleton beside the avatar, and the pose
    check's verdict (a refusal unless --no-pose-check)."""
    from loosefit.api.motion import pose_sheet

    avatar = build_avatar(args)
    sheet = pose_sheet(
        report,
        args.sheet,
        avatar=avatar,
        retarget=config,
        frames=args.sheet_frames,
        source=str(args.file),
    )
    if sheet.pose_error is None:
        print("pose check: passes (standing, feet on the floor, no joint too fast)")
    else:
        print(f"pose check: fails: {sheet.pose_error.found}")
    where = "the capture's skeleton (left) beside the avatar"
    log(f"wrote {sheet.path}: {where}, frames {sheet.frames}")
    if sheet.pose_error is not None and not args.no_pose_check:
        raise sheet.pose_error
