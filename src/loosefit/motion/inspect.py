"""What loosefit makes of a motion capture file before retargeting it (``loosefit
inspect-motion``): BVH, glTF/GLB or an SMPL pose ``.npz``.

The joints found, what drives each avatar joint and how it was decided, the
source's axes, how the bones are calibrated, the dancer's height, the units and the
frame rate, in one readable report; and for ``--sheet``, the capture's skeleton beside
the retargeted avatar (:func:`sheet_inputs`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.motion.bone_directions import zero_pose_stands
from loosefit.motion.bvh import _UNIT_SCALES
from loosefit.motion.files import read_clip
from loosefit.motion.joint_maps import AVATAR_JOINTS
from loosefit.motion.joint_match import JointMatch
from loosefit.motion.retarget import (
    DANCER_HEIGHT_M,
    RetargetConfig,
    axis_change,
    resolve_joint_map,
    source_axes,
    source_height,
    source_pose,
)
from loosefit.motion.skeleton_clip import BvhClip, body_extent
from loosefit.types import Motion


@dataclass
class MotionInspection:
    """What :func:`inspect_motion` found in a motion capture file.

    Attributes:
        clip: the file as read.
        units: how its lengths were read, e.g. "cm (guessed: the body at rest spans 171
            file units)".
        height: the dancer's height, metres, as read.
        height_how: how the height was measured.
        match: the joint map and the decision behind each avatar joint; None if there
            is none (then ``error`` says why).
        error: the error retargeting would raise for the joints, or None.
        up, forward: the source's axes (:func:`~loosefit.motion.retarget.source_axes`).
        up_how: how up was decided ("given", "found from the frames ...", "default").
        calibration: how the bones' turns are calibrated, and why
            (:mod:`~loosefit.motion.bone_directions`); "" without a joint map.
    """

    clip: BvhClip
    units: str
    height: float
    height_how: str
    match: JointMatch | None
    error: LoosefitInputError | None
    up: str = "+y"
    forward: str = "+z"
    up_how: str = "default"
    calibration: str = ""

    def format(self) -> str:
        """The report as text, one fact a line."""
        clip = self.clip
        lines = [
            f"file: {clip.path}",
            f"frames: {clip.num_frames} at {clip.fps:.4g} fps "
            f"({(clip.num_frames - 1) * clip.frame_time:.2f} s)",
            f"units: {self.units}",
        ]
        lines += [f"{k}: {v}" for k, v in clip.meta.get("report", {}).items()]
        low, high = DANCER_HEIGHT_M
        ok = low <= self.height <= high
        warn = "" if ok else f"; outside {low:g}-{high:g} m: set --units or --scale"
        lines.append(f"dancer: {self.height:.2f} m tall ({self.height_how}){warn}")
        lines.append(f"axes: up {self.up} ({self.up_how}), forward {self.forward}")
        if self.calibration:
            lines.append(f"calibration: {self.calibration}")
        lines.append(f"joints ({clip.num_joints}):")
        depth = np.zeros(clip.num_joints, dtype=np.int64)
        for j, p in enumerate(clip.parents):
            depth[j] = depth[p] + 1 if p >= 0 else 0
            lines.append(f"  {'  ' * depth[j]}{clip.joint_names[j]}")
        if self.match is None:
            return "\n".join(lines)
        jmap = self.match.joint_map
        lines.append(f"joint map: {jmap.name}")
        width = max(len(a) for a in AVATAR_JOINTS)
        src_width = max([len(s) for s in jmap.joints.values()] + [12])
        lines.append(f"  {'avatar joint':<{width}}  {'source joint':<{src_width}}  how")
        for a in AVATAR_JOINTS:
            if a in jmap.joints and a in self.match.how:
                lines.append(f"  {a:<{width}}  {jmap.joints[a]:<{src_width}}  {self.match.how[a]}")
        rest = [a for a in AVATAR_JOINTS if a not in self.match.how]
        if rest:
            lines.append(f"  not driven (they follow their parent): {', '.join(rest)}")
        used = set(jmap.joints.values())
        unused = [n for n in clip.joint_names if n not in used]
        if unused:
            lines.append(f"  source joints not used: {', '.join(unused)}")
        if jmap.align:
            lines.append(f"  limbs matched bone by bone: {', '.join(jmap.align)}")
        lines += [f"  {n}" for n in self.match.notes]
        return "\n".join(lines)


def _units(clip: BvhClip, config: RetargetConfig) -> str:
    unit = {v: k for k, v in _UNIT_SCALES.items()}.get(clip.units_scale)
    form = clip.meta.get("format")
    if form == "SMPL":
        return "m (SMPL)"
    if config.scale is not None:
        return f"{config.scale:g} m per file unit (--scale)"
    if config.units != "auto":
        return f"{config.units} (--units)"
    if form == "glTF":
        return "m (glTF's unit; --units or --scale to set)"
    scale = clip.units_scale
    ends = {j: o / scale for j, o in clip.end_offsets.items()}
    extent = body_extent(clip.parents, clip.offsets.astype(np.float64) / scale, ends)
    shape = ""
    if clip.meta.get("bones_from_frames"):
        shape = (
            f"; its OFFSETs are zero: {len(clip.meta['bones_from_frames'])} bones read from "
            "the frames' position channels"
        )
    return (
        f"{unit} (guessed: the body at rest spans {extent:.4g} file units{shape}; "
        "--units or --scale to set)"
    )


def inspect_motion(path: str | Path, config: RetargetConfig | None = None) -> MotionInspection:
    """Read a motion capture file and say how it would be retargeted with ``config``.

    Args:
        path: a ``.bvh``, ``.gltf``/``.glb`` or SMPL ``.npz`` file
            (:func:`~loosefit.motion.files.read_clip`).
        config: how it is read (units, scale, animation, skin, SMPL up axis) and
            mapped (joint map, axes), as retargeting takes them.

    Returns:
        The inspection; a skeleton that cannot be mapped comes back with ``error`` set.

    Raises:
        LoosefitInputError: for a file that cannot be read.
    """
    config = config or RetargetConfig()
    clip = read_clip(path, config)
    height, how = source_height(clip, config)
    match, error = None, None
    try:
        match = resolve_joint_map(clip, config)
    except LoosefitInputError as exc:
        error = exc
    up, forward, up_how = source_axes(clip, config, match.joint_map if match else None)
    calibration = ""
    if match is not None:
        names = list(clip.joint_names)
        present = {a: names.index(s) for a, s in match.joint_map.joints.items() if s in names}
        rest = source_pose(clip, axis_change(up, forward)).rest
        stands, why = zero_pose_stands(rest, present)
        if config.reference != "auto":
            calibration = f"{config.reference} (given)"
        elif stands:
            calibration = "zero-pose: the zero pose stands as the avatar's rest does"
        else:
            calibration = (
                f"clip: the bones' directions and bends over the clip; the zero "
                f"pose does not stand ({why})"
            )
    return MotionInspection(
        clip, _units(clip, config), height, how, match, error, up, forward, up_how, calibration
    )


@dataclass
class SheetInputs:
    """What ``inspect-motion --sheet`` draws: the capture and the avatar at a few frames.

    Attributes:
        frames: K frame numbers of the file.
        points: (K, P, 3) the source's joints then End Sites, in the avatar's axes and
            scale, its root over the avatar's.
        bones: (a, b) pairs of ``points`` indices: the bones below the pelvis.
        motion: the K frames of the retargeted motion (for the avatar's body).
    """

    frames: list[int]
    points: np.ndarray
    bones: list[tuple[int, int]]
    motion: Motion


def sheet_inputs(
    clip: BvhClip, motion: Motion, config: RetargetConfig, count: int = 6
) -> SheetInputs:
    """The source skeleton beside a motion retargeted from it at the file's own frame rate
    (``RetargetConfig(fps=None)``), at ``count`` evenly spaced frames."""
    match = resolve_joint_map(clip, config)
    up, forward, _ = source_axes(clip, config, match.joint_map)
    names = list(clip.joint_names)
    root = names.index(match.joint_map.joints["Hips"])
    pose = source_pose(clip, axis_change(up, forward), root)
    ends = sorted(clip.end_offsets)
    end_pts = [pose.positions[:, j] + pose.leaf[j][0] for j in ends]
    points = (
        np.concatenate([pose.positions, np.stack(end_pts, 1)], 1) if ends else pose.positions
    )  # (T, P, 3)
    scale = float(motion.meta.get("scale", 1.0))
    points = points * scale
    points += motion.root_translation[0] - points[0, root]  # the recentring and grounding
    body = {root}  # the pelvis's subtree: joints above it (a scene root) are no bones
    for j, p in enumerate(clip.parents):
        if p in body:
            body.add(j)
    bones = [(int(p), j) for j, p in enumerate(clip.parents) if p in body and j in body]
    bones += [(j, clip.num_joints + k) for k, j in enumerate(ends) if j in body]
    T = min(motion.num_frames, clip.num_frames)
    frames = sorted(set(np.linspace(0, T - 1, min(count, T)).round().astype(int).tolist()))
    part = Motion(
        motion.joint_names,
        motion.rotations[frames],
        motion.root_translation[frames],
        motion.fps,
        motion.name,
    )
    return SheetInputs(frames, points[frames], bones, part)
