"""What a body's motion does that can push cloth into it, frame by frame.

:func:`motion_signals` measures, for every frame of a posed body: the root's angular
speed about the vertical (a spin), how close each hand comes to the skin a skirt covers,
the gap between the thighs, and how deep each limb is buried in the rest of the body (a
self-intersecting pose, which closes a fold of skin over whatever cloth lies in it).
Pure functions of arrays and a :class:`~loosefit.body.regions.BodyParts`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from loosefit.body.regions import BodyParts
from loosefit.errors import LoosefitInputError
from loosefit.eval.heading import fastest_turn as heading_fastest_turn
from loosefit.eval.heading import turn_rate as heading_turn_rate
from loosefit.eval.heading import yaw_rate
from loosefit.geometry.query import Surface

# m: a limb vertex deeper than this inside the rest of the body makes the pose
# self-intersecting; shallower, it is the skin creasing (armpit, groin, back of the knee)
SELF_INTERSECTION_TOLERANCE = 0.01


def spin_rate(root_rotations: np.ndarray, fps: float) -> np.ndarray:
    """(T,) rad/s, the root's angular speed about the vertical (+ is counter-clockwise seen
    from above), from its heading (:func:`~loosefit.model.motion_features.heading_yaw`).

    Args:
        root_rotations: (T, 3, 3) the root joint's world rotation (rest to posed).
        fps: frames per second.
    """
    R = np.asarray(root_rotations, np.float64)
    if R.ndim != 3 or R.shape[1:] != (3, 3):
        raise LoosefitInputError("spin_rate", "root_rotations", "shape (T, 3, 3)", f"{R.shape}")
    if len(R) < 2:
        return np.zeros(len(R))
    return yaw_rate(R, fps, "gradient")


@dataclass
class MotionSignals:
    """Per-frame figures of the body's motion that push cloth into it.

    Attributes:
        spin: (T,) rad/s about the vertical (:func:`spin_rate`).
        hand_hip: (T, 2) m, the smallest distance from a vertex of the (left, right) hand
            to the skin a skirt covers (:data:`~loosefit.body.regions.HIP_ZONE`: hips,
            waist, thighs); inf without hands.
        thigh_gap: (T,) m, the smallest distance from a left-thigh vertex (but the groin's,
            :data:`~loosefit.body.regions.THIGH_REST_CLEARANCE`) to the right thigh's
            skin.
        limbs: the limbs tested for self-intersection, in the order of the columns below.
        limb_collides: per limb, whether the cloth collides with it (its skin in the
            collider); only that skin is tested, or all of it where none collides.
        self_depth: (T, L) m, how deep the limb's deepest vertex is inside the rest of
            the body (0 where none is inside).
        self_count: (T, L) limb vertices deeper than ``self_tolerance`` there.
        self_region: (T, L) int64 region the deepest vertex is inside (-1 where none).
        self_vertex: (T, L) int64 that body vertex (-1 where none).
        self_tolerance: m (:data:`SELF_INTERSECTION_TOLERANCE`).
    """

    spin: np.ndarray
    hand_hip: np.ndarray
    thigh_gap: np.ndarray
    limbs: tuple[str, ...]
    limb_collides: tuple[bool, ...]
    self_depth: np.ndarray
    self_count: np.ndarray
    self_region: np.ndarray
    self_vertex: np.ndarray
    self_tolerance: float

    @property
    def self_intersecting(self) -> np.ndarray:
        """(T,) bool: some limb is deeper than ``self_tolerance`` inside the body."""
        return (self.self_count > 0).any(axis=1)


def motion_signals(
    body: np.ndarray,
    root_rotations: np.ndarray,
    fps: float,
    parts: BodyParts,
    self_tolerance: float = SELF_INTERSECTION_TOLERANCE,
    progress: Callable[[int, int], None] | None = None,
) -> MotionSignals:
    """Spin, hand-hip distance, thigh gap and self-intersection of every frame.

    Self-intersection of a limb: its vertices inside the closed mesh of the rest of the
    collider (of the whole body, for a limb the cloth does not collide with), the limb cut
    away and the holes capped (``BodyParts.limb_faces``), by the winding number, deeper
    than ``self_tolerance``: a thigh folded into the belly, one thigh through the other,
    a hand buried in the hip.

    Args:
        body: (T, Vb, 3) the posed body.
        root_rotations: (T, 3, 3) the root's world rotation.
        fps: frames per second.
        parts: :func:`~loosefit.body.regions.body_parts`.
        self_tolerance: m.
        progress: called as ``progress(done, T)`` after each frame.

    Returns:
        :class:`MotionSignals`.
    """
    b = np.asarray(body, np.float32)
    if b.ndim != 3 or b.shape[1:] != (len(parts.region), 3):
        raise LoosefitInputError(
            "motion_signals", "body", f"shape (T, {len(parts.region)}, 3)", f"{b.shape}"
        )
    T = len(b)
    limbs = tuple(parts.limb_faces)
    tests = [parts.tested_vertices(limb) for limb in limbs]  # (vertices, collides) each
    tested = [v for v, _ in tests]
    hip = Surface(b[0], parts.hip_faces) if len(parts.hip_faces) else None
    right = Surface(b[0], parts.right_thigh_faces) if len(parts.right_thigh_faces) else None
    rest_of = {limb: Surface(b[0], parts.limb_faces[limb]) for limb in limbs}
    hand_hip = np.full((T, 2), np.inf)
    thigh_gap = np.full(T, np.inf)
    depth = np.zeros((T, len(limbs)))
    count = np.zeros((T, len(limbs)), np.int64)
    region = np.full((T, len(limbs)), -1, np.int64)
    vertex = np.full((T, len(limbs)), -1, np.int64)
    for t in range(T):
        if hip is not None:
            hip.refit(b[t])
            for side, hand in enumerate(parts.hand_vertices):
                if len(hand):
                    hand_hip[t, side] = hip.query(b[t, hand], sign="normal").distance.min()
        if right is not None and len(parts.thigh_vertices):
            right.refit(b[t])
            thigh_gap[t] = right.query(b[t, parts.thigh_vertices], sign="normal").distance.min()
        for j, limb in enumerate(limbs):
            s = rest_of[limb]
            s.refit(b[t])
            hit = s.query(b[t, tested[j]])
            inside = hit.inside & (hit.faces >= 0)
            if not inside.any():
                continue
            d = np.where(inside, hit.distance, 0.0)
            k = int(np.argmax(d))
            depth[t, j] = d[k]
            count[t, j] = int((d > self_tolerance).sum())
            vertex[t, j] = tested[j][k]
            region[t, j] = parts.face_region(
                s.faces, hit.faces[k : k + 1], hit.barycentric[k : k + 1]
            )[0]
        if progress is not None:
            progress(t + 1, T)
    return MotionSignals(
        spin=spin_rate(root_rotations, fps),
        hand_hip=hand_hip,
        thigh_gap=thigh_gap,
        limbs=limbs,
        limb_collides=tuple(c for _, c in tests),
        self_depth=depth,
        self_count=count,
        self_region=region,
        self_vertex=vertex,
        self_tolerance=float(self_tolerance),
    )


def buried_vertices(parts: BodyParts, limb: str, body: np.ndarray, tolerance: float) -> np.ndarray:
    """(n,) the limb's tested vertices deeper than ``tolerance`` inside the rest of the
    body (Vb, 3) (its ``limb_faces``)."""
    tested, _ = parts.tested_vertices(limb)
    hit = Surface(body, parts.limb_faces[limb]).query(body[tested])
    return tested[hit.inside & (hit.faces >= 0) & (hit.distance > tolerance)]


def turn_rate(motion, window: int = 5) -> np.ndarray:
    """(T,) how fast the heading turns at each frame (rad/s, a centred mean over ``window``
    frames; the first frame 0)."""
    R = np.asarray(motion.rotations[:, 0], np.float64)
    return heading_turn_rate(R, motion.fps, window, "step")


def fastest_turn(motion, window: int = 5) -> int:
    """The motion frame where the heading turns fastest (:func:`turn_rate`)."""
    R = np.asarray(motion.rotations[:, 0], np.float64)
    return heading_fastest_turn(R, motion.fps, window, "step")


def turn_extent(
    rate: np.ndarray, frame: int, fps: float, fraction: float = 0.5
) -> tuple[float, float]:
    """How long a turn lasts and how far it turns: the run of frames around ``frame`` where
    the rate keeps its sign and at least ``fraction`` of its size there.

    Args:
        rate: (T,) the heading's turn rate (rad/s, :func:`turn_rate`).
        frame: a frame of the turn (its fastest, :func:`fastest_turn`).
        fps: frames a second.

    Returns:
        (seconds, turns): the run's length, and the heading's turn over it in turns (its
        size; a brief flick and a built-up pirouette of one peak rate tell apart here);
        (0, 0) at a frame that does not turn.
    """
    rate = np.asarray(rate, np.float64)
    peak = rate[frame]
    if peak == 0:
        return 0.0, 0.0
    inside = np.sign(rate) == np.sign(peak)
    inside &= np.abs(rate) >= fraction * abs(peak)
    first = last = frame
    while first > 0 and inside[first - 1]:
        first -= 1
    while last < len(rate) - 1 and inside[last + 1]:
        last += 1
    span = rate[first : last + 1]
    return (last - first + 1) / fps, float(abs(span.sum()) / fps / (2.0 * np.pi))


def highest_leg(joints_z: np.ndarray) -> tuple[int, float]:
    """The frame where one foot is highest above the other, and that height (m).

    Args:
        joints_z: (T, 2) the left and right foot joints' heights.
    """
    gap = np.abs(joints_z[:, 0] - joints_z[:, 1])
    return int(np.argmax(gap)), float(gap.max())
