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

from loosefit.errors import LoosefitInputError
from loosefit.geometry.rotations import matrix_to_quat, quat_slerp, quat_to_matrix
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


def blend_frames(
    rot0: np.ndarray, root0: np.ndarray, rot1: np.ndarray, root1: np.ndarray, n: int
) -> tuple[np.ndarray, np.ndarray]:
    """The ``n`` frames strictly between two poses: local rotations slerped, the root lerped,
    smoothstep timing (the transitions of a chain and the blend before a rollout).

    Args:
        rot0, rot1: (J, 3, 3) local rotations of the poses; root0, root1: (3,) their roots.
        n: frames between them.

    Returns:
        rotations (n, J, 3, 3) and roots (n, 3), in the inputs' float type.
    """
    w = np.arange(1, n + 1) / (n + 1.0)
    w = w * w * (3.0 - 2.0 * w)  # (n,) smoothstep
    q0, q1 = matrix_to_quat(rot0), matrix_to_quat(rot1)  # (J, 4) each
    rotations = quat_to_matrix(quat_slerp(q0[None], q1[None], w[:, None]))  # (n, J, 3, 3)
    return rotations, root0 + w[:, None] * (root1 - root0)


def preroll(
    motion: Motion,
    floor_height: float,
    settle_seconds: float,
    blend_seconds: float,
    settle_at_start: bool = True,
) -> tuple[np.ndarray, np.ndarray, int]:
    """The settle and blend frames that come before a motion (a simulation's and a rollout's).

    Settle: the rest pose standing on the floor, for ``settle_seconds`` (one frame
    more, so that the cloth settles for exactly that long). With
    ``settle_at_start`` (the simulator's and the rollout's choice) it stands where
    the motion starts, turned to its heading (the root's yaw); otherwise at the
    origin facing -Y. Blend: :func:`blend_frames` into the motion's first frame
    over ``blend_seconds``.

    Args:
        motion: the motion that follows (T, J joints).
        floor_height: the avatar's root height when standing.
        settle_seconds, blend_seconds: the two durations (``ClothConfig``'s fields of
            those names in a simulation).
        settle_at_start: stand where the motion starts rather than at the origin.

    Returns:
        rotations (P, J, 3, 3) float32, root translations (P, 3) float32, and the
        number of settle frames (the first frames of the P).
    """
    J = motion.num_joints
    n_settle = int(round(settle_seconds * motion.fps)) + 1
    n_blend = int(round(blend_seconds * motion.fps))
    rest_rot = np.broadcast_to(np.eye(3, dtype=np.float32), (J, 3, 3)).copy()
    rest_root = np.array([0.0, 0.0, floor_height], np.float32)
    if settle_at_start:
        forward = motion.rotations[0, 0] @ np.array([0.0, -1.0, 0.0], np.float32)
        if np.hypot(forward[0], forward[1]) > 1e-6:  # else the root looks straight up/down
            rest_rot[0] = _rot_z(math.atan2(forward[0], -forward[1]))
        rest_root[:2] = motion.root_translation[0, :2]
    blend_rot, blend_root = blend_frames(
        rest_rot, rest_root, motion.rotations[0], motion.root_translation[0], n_blend
    )
    rotations = np.concatenate([np.broadcast_to(rest_rot, (n_settle, J, 3, 3)), blend_rot])
    root = np.concatenate([np.broadcast_to(rest_root, (n_settle, 3)), blend_root])
    return rotations.astype(np.float32), root.astype(np.float32), n_settle


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
                f"motion '{m.name}'",
                "joint_names",
                f"the joints of '{first.name}'",
                f"{len(m.joint_names)} other joints",
            )
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
            start_rot = placed.rotations[0].astype(np.float64)
            start = placed.root_translation[0].astype(np.float64)
            rot, root = blend_frames(last_rot, last_root, start_rot, start, n_blend)
            rotations.append(rot)
            roots.append(root)
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
