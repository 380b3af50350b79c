"""Motions through the API: the avatar a motion plays on, how a motion capture file is read
(its units, its joint map, the pose check), and a file inspected before it is used: what it
holds, a joint map file to correct by hand, and a sheet of its skeleton beside the avatar.

::

    from loosefit.api.motion import build_avatar, inspect_motion, pose_sheet, retarget_config

    config = retarget_config(units="cm")
    report = inspect_motion("capture.bvh", retarget=config)
    print(report.format())
    sheet = pose_sheet(report, "sheet.png", avatar=build_avatar(), retarget=config)

A motion itself, on the avatar's skeleton, comes from :func:`loosefit.api.motion_for`.
Each function imports what it needs when called, so that importing this module stays
quick (the commands read :func:`bvh_units` while their parser is built).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path


def bvh_units() -> tuple[str, ...]:
    """The length units a BVH file may be read in (``"auto"``: guessed from its skeleton's
    size; :data:`loosefit.motion.bvh.BVH_UNITS`)."""
    from loosefit.motion.bvh import BVH_UNITS  # numpy only

    return tuple(BVH_UNITS)


def retarget_config(
    *,
    units: str = "auto",
    scale: float | None = None,
    joint_map: str = "auto",
    animation: str | None = None,
    skin: str | None = None,
    smpl_up: str = "auto",
    check_pose: bool = True,
):
    """How a motion capture file is read and mapped onto the avatar, as
    :func:`loosefit.api.motion_for`, :meth:`loosefit.api.Animator.animate` and
    :func:`inspect_motion` take it (a :class:`~loosefit.motion.retarget.RetargetConfig`;
    the fields not named here keep their defaults).

    Args:
        units: a BVH file's length unit, one of :func:`bvh_units`.
        scale: a BVH file's metres per unit (overrides ``units``); None: from ``units``.
        joint_map: ``"auto"``, a shipped map's name (``daz``, ``cmu_mb``), or a
            ``.yaml``/``.toml`` file of "avatar joint: your joint" lines.
        animation: a glTF file's animation, by name or index (None: the first).
        skin: a glTF file's skin, by name or index (None: the one its animation drives most).
        smpl_up: an SMPL ``.npz``'s world up axis (``"+z"`` for AMASS; ``"auto"``: found).
        check_pose: refuse a motion no dancer could dance (the pose check).
    """
    from loosefit.motion.retarget import RetargetConfig

    return RetargetConfig(
        units=units,
        scale=scale,
        joint_map=joint_map,
        animation=animation,
        skin=skin,
        smpl_up=smpl_up,
        check_pose=check_pose,
    )


def build_avatar(shape: dict[str, float] | None = None, *, device: str = "cpu"):
    """The avatar (NAVER's anny) of a body shape, posed on ``device``: a
    :class:`~loosefit.body.avatar.Avatar`, which poses motions (``pose_motion``) and
    checks them (``check_motion``). The first call on a machine builds anny's cache
    (about 2 minutes).

    Args:
        shape: anny phenotypes in [0, 1], e.g. ``{"gender": 0.9, "height": 0.6}``;
            None or empty: the default body.
        device: the torch device it poses on (``"cpu"``, ``"cuda"``).
    """
    from loosefit.body.avatar import Avatar, AvatarConfig

    return Avatar(AvatarConfig(shape=dict(shape or {})), device=device)


def inspect_motion(path: str | Path, *, retarget=None):
    """How a motion capture file (BVH, glTF/GLB, SMPL ``.npz``) would be read, without
    refusing it: a :class:`~loosefit.motion.inspect.MotionInspection` (``format()`` its
    report; ``clip`` the file as read; ``match`` each avatar joint's source joint and why;
    ``error`` what retargeting would refuse, or None).

    Args:
        path: the file.
        retarget: how it is read (:func:`retarget_config`; None: the defaults).
    """
    from loosefit.motion.inspect import inspect_motion as inspect

    return inspect(path, retarget)


def joint_map_text(report, source: str) -> str:
    """A joint map file (YAML) filled in with what :func:`inspect_motion` matched (or,
    where nothing could be, guessed by name), to correct by hand and pass as
    ``joint_map``; ``source`` names the file it is for in its header."""
    from loosefit.motion.joint_map_files import joint_map_template

    clip = report.clip
    axes = (report.up, report.forward)
    return joint_map_template(clip.joint_names, report.match, source, axes, clip.parents)


@dataclass
class PoseSheet:
    """What :func:`pose_sheet` found and wrote.

    Attributes:
        path: the PNG written.
        frames: the file's frames on it.
        pose_error: why the retargeted poses fail the pose check (the refusal
            :func:`loosefit.api.motion_for` would raise with the check on), or None: they
            pass.
    """

    path: Path
    frames: list[int]
    pose_error: Exception | None


def pose_sheet(
    report,
    out: str | Path,
    *,
    avatar,
    retarget=None,
    frames: int = 6,
    source: str | None = None,
) -> PoseSheet:
    """A capture's skeleton beside the avatar: the file of ``report``
    (:func:`inspect_motion`) retargeted onto ``avatar`` at its own frame rate, its poses
    checked, and a contact sheet written to ``out`` (its folder made): the capture's
    skeleton as sticks (left) beside the avatar's body, at ``frames`` evenly spaced frames.
    Drawn whatever the pose check says (the sheet is how to see why it fails); the check's
    verdict comes back in :attr:`PoseSheet.pose_error`.

    Args:
        report: what :func:`inspect_motion` read of the file.
        out: the PNG to write.
        avatar: the avatar to retarget onto (:func:`build_avatar`).
        retarget: how the file is read (:func:`retarget_config`; None: the defaults).
        frames: how many frames the sheet shows.
        source: the file's name in the pose check's refusal (None: its path as read).
    """
    from PIL import Image

    from loosefit.errors import LoosefitInputError
    from loosefit.motion.inspect import sheet_inputs
    from loosefit.motion.pose_check import check_pose
    from loosefit.motion.retarget import RetargetConfig, retarget_bvh
    from loosefit.render.skeleton_sheet import skeleton_sheet

    config = retarget if retarget is not None else RetargetConfig()
    loose = dataclasses.replace(config, fps=None, check_pose=False, check_height=False)
    motion = retarget_bvh(report.clip, avatar.skeleton, avatar.floor_height, loose)
    pose_error = None
    try:
        check_pose(motion, avatar.skeleton, avatar.floor_height, source or str(report.clip.path))
    except LoosefitInputError as exc:
        pose_error = exc
    sheet = sheet_inputs(report.clip, motion, loose, frames)
    body = avatar.pose_motion(sheet.motion).vertices.cpu().numpy()
    faces = avatar.faces.cpu().numpy()
    image = skeleton_sheet(sheet.points, sheet.bones, body, faces, sheet.frames)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(image).save(out)
    return PoseSheet(out, sheet.frames, pose_error)
