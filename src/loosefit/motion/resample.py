"""Change a motion's frame rate or playing speed, and remove single-frame rotation pops.

Resampling keeps the clip's time span: new frames sit at ``k / dst_fps`` for
``k = 0 .. floor(duration * dst_fps)``, with ``duration = (T - 1) / src_fps``, so the
first frame is kept and the last new frame is at or before the last old one.
Each new frame blends the two old frames that bracket it: rotations by quaternion
slerp (along the shorter arc), translations linearly.
"""

from __future__ import annotations

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.geometry.rotations import matrix_to_quat, quat_slerp, quat_to_matrix, rotation_angle
from loosefit.types import Motion


def _check_fps(name: str, fps: float) -> None:
    if not (np.isfinite(fps) and fps > 0):
        raise LoosefitInputError("resample", name, "a positive frame rate", repr(fps))


def resample_times(
    num_frames: int, src_fps: float, dst_fps: float
) -> tuple[np.ndarray, np.ndarray]:
    """Where the new frames fall among the old ones.

    Args:
        num_frames: T, the number of source frames (>= 1).
        src_fps: source frame rate.
        dst_fps: target frame rate.

    Returns:
        index: (T',) int64 index ``i`` of the old frame at or before each new frame,
            at most ``T - 2`` (0 when T = 1).
        weight: (T',) float64 fraction in [0, 1] of the way from frame ``i`` to ``i + 1``.
        ``T' = floor((T - 1) / src_fps * dst_fps) + 1`` (a 1e-9 tolerance absorbs
        rounding so that e.g. 121 frames at 120 fps give exactly 31 at 30 fps).
    """
    _check_fps("src_fps", src_fps)
    _check_fps("dst_fps", dst_fps)
    if num_frames < 1:
        raise LoosefitInputError("resample", "frames", "at least one frame", str(num_frames))
    count = int(np.floor((num_frames - 1) * dst_fps / src_fps + 1e-9)) + 1
    u = np.arange(count) * (src_fps / dst_fps)  # (T',) positions in old frames
    u = np.minimum(u, num_frames - 1)
    index = np.minimum(np.floor(u).astype(np.int64), max(num_frames - 2, 0))
    weight = np.clip(u - index, 0.0, 1.0)
    if num_frames == 1:
        weight = np.zeros_like(weight)
    return index, weight


def resample_linear(x: np.ndarray, src_fps: float, dst_fps: float) -> np.ndarray:
    """Resample a sequence by linear interpolation between bracketing frames.

    Args:
        x: (T, ...) values per frame (e.g. root translations (T, 3)).
        src_fps: frame rate of ``x``.
        dst_fps: target frame rate.

    Returns:
        (T', ...) resampled values, dtype of ``x`` if floating else float64;
        T' as in :func:`resample_times`.
    """
    x = np.asarray(x)
    index, weight = resample_times(x.shape[0], src_fps, dst_fps)
    nxt = np.minimum(index + 1, x.shape[0] - 1)
    w = weight.reshape(-1, *([1] * (x.ndim - 1)))  # (T', 1, ...)
    out = (1.0 - w) * x[index] + w * x[nxt]
    return out.astype(x.dtype if np.issubdtype(x.dtype, np.floating) else np.float64)


def resample_rotations(rotations: np.ndarray, src_fps: float, dst_fps: float) -> np.ndarray:
    """Resample rotation matrices by slerp between bracketing frames.

    Args:
        rotations: (T, J, 3, 3) rotation matrices (any number of joints; the
            joint axis may also be absent: (T, 3, 3)).
        src_fps: frame rate of ``rotations``.
        dst_fps: target frame rate.

    Returns:
        (T', J, 3, 3) float32 rotation matrices; T' as in :func:`resample_times`.
    """
    rot = np.asarray(rotations)
    index, weight = resample_times(rot.shape[0], src_fps, dst_fps)
    nxt = np.minimum(index + 1, rot.shape[0] - 1)
    quat = matrix_to_quat(rot)  # (T, J, 4)
    w = weight.reshape(-1, *([1] * (quat.ndim - 2)))  # (T', 1) broadcast over joints
    out = quat_slerp(quat[index], quat[nxt], w)  # (T', J, 4)
    return quat_to_matrix(out)


def resample_motion(motion: Motion, fps: float) -> Motion:
    """A motion at a new frame rate over the same time span.

    Rotations are slerped, the root translation is interpolated linearly.

    Args:
        motion: the source motion, T frames.
        fps: the target frame rate.

    Returns:
        A new :class:`Motion` with ``floor(motion.duration * fps) + 1`` frames at ``fps``.
    """
    _check_fps("fps", fps)
    meta = dict(motion.meta)
    meta.setdefault("resampled_from_fps", motion.fps)
    return Motion(
        motion.joint_names,
        resample_rotations(motion.rotations, motion.fps, fps),
        resample_linear(motion.root_translation, motion.fps, fps),
        float(fps),
        motion.name,
        meta,
    )


def retime_motion(motion: Motion, speed: float) -> Motion:
    """The motion played ``speed`` times as fast, at its own frame rate.

    New frame ``k`` shows the pose at ``k * speed / fps`` seconds of the source
    (rotations slerped, the root translation interpolated linearly, as in
    :func:`resample_motion`), so ``speed = 1.25`` gives a clip 20 % shorter whose
    root moves and turns 25 % faster.

    Args:
        motion: the source motion, T frames at ``motion.fps``.
        speed: how many times as fast; positive and finite.

    Returns:
        A new :class:`Motion` of ``floor((T - 1) / speed) + 1`` frames at
        ``motion.fps``, named ``speed:SPEED:NAME``.
    """
    if not (np.isfinite(speed) and speed > 0):
        raise LoosefitInputError(
            f"motion '{motion.name}'", "speed", "a positive finite factor", repr(speed)
        )
    fps = motion.fps
    meta = {**motion.meta, "speed": float(motion.meta.get("speed", 1.0)) * float(speed)}
    return Motion(
        motion.joint_names,
        resample_rotations(motion.rotations, fps, fps / speed),
        resample_linear(motion.root_translation, fps, fps / speed),
        float(fps),
        f"speed:{speed:g}:{motion.name}",
        meta,
    )


def detect_rotation_glitches(
    rotations: np.ndarray, fps: float, max_deg_per_frame_at_120: float = 15.0
) -> np.ndarray:
    """Find single-frame rotation pops.

    Rule, per joint and interior frame ``t`` (the first and last frames are never
    flagged), with ``d(a, b)`` the angle of the rotation from frame ``a`` to frame
    ``b`` and ``thr = max_deg_per_frame_at_120 * 120 / fps`` (the same angular
    speed at any frame rate): frame ``t`` is a glitch when ``d(t-1, t) > thr`` and
    ``d(t, t+1) > thr`` while ``d(t-1, t+1) < thr``: the joint jumps away and back
    while its neighbours agree. A real motion cannot reverse that fast (15 degrees
    in one 120 fps frame and straight back is 1,800 deg/s with a turn-around
    within 8 ms). If two consecutive frames both meet the rule (a two-frame
    wobble) neither is a single-frame pop and neither is flagged. Pops lasting two
    or more frames are not detected.

    Args:
        rotations: (T, J, 3, 3) local rotation matrices.
        fps: their frame rate.
        max_deg_per_frame_at_120: the angular step, in degrees per frame at 120 fps,
            above which a jump counts as large.

    Returns:
        (T, J) bool, True at glitch frames.
    """
    _check_fps("fps", fps)
    rot = np.asarray(rotations)
    if rot.ndim != 4 or rot.shape[-2:] != (3, 3):
        raise LoosefitInputError(
            "detect_rotation_glitches", "rotations", "shape (T, J, 3, 3)", f"shape {rot.shape}"
        )
    T, J = rot.shape[:2]
    flagged = np.zeros((T, J), dtype=bool)
    if T < 3:
        return flagged
    thr = np.deg2rad(max_deg_per_frame_at_120 * 120.0 / fps)
    step = rotation_angle(rot[:-1], rot[1:])  # (T-1, J): d(t, t+1)
    skip = rotation_angle(rot[:-2], rot[2:])  # (T-2, J): d(t-1, t+1)
    flagged[1:-1] = (step[:-1] > thr) & (step[1:] > thr) & (skip < thr)  # t = 1 .. T-2
    # Keep isolated flags only: a flagged neighbour means it is not a single-frame pop.
    isolated = flagged.copy()
    isolated[1:] &= ~flagged[:-1]
    isolated[:-1] &= ~flagged[1:]
    return isolated


def filter_rotation_glitches(
    rotations: np.ndarray, fps: float, max_deg_per_frame_at_120: float = 15.0
) -> np.ndarray:
    """Replace single-frame rotation pops by the slerp midpoint of their neighbours.

    Glitch frames are found by :func:`detect_rotation_glitches` (see there for the
    rule); every other frame is returned unchanged.

    Args:
        rotations: (T, J, 3, 3) local rotation matrices.
        fps: their frame rate.
        max_deg_per_frame_at_120: the angular step, in degrees per frame at 120 fps,
            above which a jump counts as large.

    Returns:
        (T, J, 3, 3) float32 rotations with the glitch frames replaced.
    """
    glitches = detect_rotation_glitches(rotations, fps, max_deg_per_frame_at_120)
    rot = np.asarray(rotations)
    out = rot.astype(np.float32, copy=True)
    t, j = np.nonzero(glitches)
    if len(t):
        q0, q1 = matrix_to_quat(rot[t - 1, j]), matrix_to_quat(rot[t + 1, j])  # (G, 4) each
        out[t, j] = quat_to_matrix(quat_slerp(q0, q1, 0.5))
    return out
