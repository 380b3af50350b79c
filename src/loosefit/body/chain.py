"""Chaining motions into one long, continuous motion.

Mocap clips are short (the CMU salsa takes run 14-19 s at 30 fps), while a
rollout must be judged over 1,200 frames or more (paper 4.3). A chain plays
clips one after the other: each next clip is turned about the vertical and
moved on the floor so that it starts where and facing how the previous one
ended, and a short transition blends the last pose into the next clip's first
(local rotations slerped, root height lerped, smoothstep timing).
"""

from __future__ import annotations

import math

import numpy as np

from loosefit.body.rotations import matrix_to_quat, quat_slerp, quat_to_matrix
from loosefit.errors import LoosefitInputError
from loosefit.types import Motion


def heading_yaw(root_rotation: np.ndarray) -> float:
    """The yaw (radians about +Z) that takes -Y, the rest facing, to the root's facing.

    Args:
        root_rotation: (3, 3) the root joint's rotation.
    """
    forward = root_rotation @ np.array([0.0, -1.0, 0.0])
    if math.hypot(forward[0], forward[1]) < 1e-6:  # looking straight up or down
        return 0.0
    return math.atan2(forward[0], -forward[1])


def _rot_z(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def place_motion(motion: Motion, yaw: float, xy: np.ndarray) -> Motion:
    """The motion turned by ``yaw`` about +Z through its first root position, then moved there.

    Args:
        motion: T frames.
        yaw: radians; positive turns counter-clockwise seen from above.
        xy: (2,) floor position for the root at frame 0.

    Returns:
        A motion whose root starts at ``(xy, z0)`` and whose every frame is turned by ``yaw``.
    """
    R = _rot_z(yaw)
    rotations = motion.rotations.astype(np.float64).copy()
    rotations[:, 0] = R @ rotations[:, 0]
    offset = motion.root_translation.astype(np.float64) - motion.root_translation[0]
    root = offset @ R.T
    root[:, :2] += np.asarray(xy, np.float64)
    root[:, 2] += motion.root_translation[0, 2]
    return Motion(motion.joint_names, rotations, root, motion.fps, motion.name, dict(motion.meta))


def chain_motions(motions: list[Motion], blend_seconds: float = 0.5, name: str = "") -> Motion:
    """Play ``motions`` one after another as one continuous motion.

    Each motion after the first is placed (:func:`place_motion`) to start at the
    previous one's last floor position and heading; ``round(blend_seconds * fps)``
    transition frames go between them.

    Args:
        motions: at least one motion, all on the same joints at the same fps.
        blend_seconds: the transition between two motions.
        name: the chain's name (default: the names joined by ``+``).

    Returns:
        A motion of ``sum(T_i) + (n - 1) * blend`` frames; ``meta["segments"]``
        lists ``(name, first_frame, num_frames)`` for each clip.
    """
    if not motions:
        raise LoosefitInputError("chain_motions", "motions", "at least one motion", "none")
    first = motions[0]
    for m in motions[1:]:
        if m.joint_names != first.joint_names:
            raise LoosefitInputError(
                f"motion '{m.name}'", "joint_names", f"the joints of '{first.name}'",
                f"{len(m.joint_names)} other joints",
            )  # fmt: skip
        if abs(m.fps - first.fps) > 1e-6:
            raise LoosefitInputError(f"motion '{m.name}'", "fps", first.fps, m.fps)
    if not blend_seconds >= 0:
        raise LoosefitInputError("chain_motions", "blend_seconds", ">= 0", blend_seconds)
    n_blend = int(round(blend_seconds * first.fps))
    rotations = [first.rotations.astype(np.float64)]
    roots = [first.root_translation.astype(np.float64)]
    segments = [(first.name, 0, first.num_frames)]
    frame = first.num_frames
    for m in motions[1:]:
        last_rot, last_root = rotations[-1][-1], roots[-1][-1]
        yaw = heading_yaw(last_rot[0]) - heading_yaw(m.rotations[0, 0].astype(np.float64))
        placed = place_motion(m, yaw, last_root[:2])
        if n_blend:
            w = np.arange(1, n_blend + 1) / (n_blend + 1.0)
            w = w * w * (3.0 - 2.0 * w)  # (B,)
            q0 = matrix_to_quat(last_rot)  # (J, 4)
            q1 = matrix_to_quat(placed.rotations[0].astype(np.float64))
            rotations.append(quat_to_matrix(quat_slerp(q0[None], q1[None], w[:, None])))
            start = placed.root_translation[0].astype(np.float64)
            roots.append(last_root + w[:, None] * (start - last_root))
            frame += n_blend
        rotations.append(placed.rotations.astype(np.float64))
        roots.append(placed.root_translation.astype(np.float64))
        segments.append((m.name, frame, m.num_frames))
        frame += m.num_frames
    return Motion(
        first.joint_names,
        np.concatenate(rotations).astype(np.float32),
        np.concatenate(roots).astype(np.float32),
        first.fps,
        name or "+".join(m.name for m in motions),
        {"segments": segments},
    )
