"""A check that an imported motion is one a dancer could dance, before anything runs on it.

Three tests on the motion as the avatar dances it (its joints' forward kinematics, no
mesh), at the capture's own frame rate, each measured on every procedural move, the 14
CMU salsa and 17 CMU ballet clips (cartwheel, leaps, turns, legs above the hip) before
its threshold was set (``bench/data/pose_check_margins.py`` prints the figures):

1. **It stands**: the head above the hips and the hips above the lower foot, in most
   frames (:data:`MIN_UPRIGHT`).
2. **Its feet meet the floor**: the lower sole within :data:`CONTACT_M` of the floor in
   enough frames (:data:`MIN_CONTACT`), and never deep below it (:data:`MAX_BELOW_M`).
3. **No limb turns faster than a joint allows**: each bone's direction in its parent's
   frame (the root's in the world) turns at most :data:`MAX_TURN_DEG_S` degrees per
   second between two frames, so at most that over the motion's frame rate per frame.

A retargeting gone wrong (a pelvis a quarter turn off, a torso folded, a leg raised
behind, arms swapped at one frame) fails one of them; :func:`check_pose` refuses it
naming the frames and the joints.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from loosefit.body.avatar import Skeleton
from loosefit.errors import LoosefitInputError
from loosefit.types import Motion

# The check's thresholds; the figures they were chosen from (bench/data/pose_check_margins.py):
# docs/design/notes/pose_check.md.
# 1. upright: the fraction of frames with the head above the hips by HEAD_MARGIN of its
# height above them at rest and the hips above the lower ankle by STAND_MARGIN of theirs
MIN_UPRIGHT = 0.75
STAND_MARGIN = 0.5
HEAD_MARGIN = 0.15  # cos(81 degrees): the head above the hips by this much of the torso
# 2. on the floor: the lower sole within CONTACT_M (m) of the floor in at least MIN_CONTACT of
# the frames, and never more than MAX_BELOW_M (m) below it
CONTACT_M = 0.10
MIN_CONTACT = 0.3
MAX_BELOW_M = 0.25
# 3. deg/s: the fastest a bone's direction may turn in its parent's frame (the root's in the
# world), frame to frame at the clip's rate
MAX_TURN_DEG_S = 9000.0


@dataclass(frozen=True)
class PoseMeasures:
    """What :func:`measure_pose` finds, frame by frame.

    Attributes:
        head_up: (T,) bool, the head above the hips by HEAD_MARGIN of its rest height
            above them.
        hips_up: (T,) bool, the hips above the lower foot by STAND_MARGIN of theirs.
        sole: (T,) float, the lower sole's height above the floor, metres.
        turn: (T - 1, J) float, degrees per second each bone's direction turns in its
            parent's frame (the root's in the world) from frame t to t + 1.
        fps: the motion's frame rate.
        torso_rise: (T,) the head's height above the hips over that at rest.
        legs_rise: (T,) the hips' height above the lower ankle over that at rest.
    """

    head_up: np.ndarray
    hips_up: np.ndarray
    sole: np.ndarray
    turn: np.ndarray
    fps: float
    torso_rise: np.ndarray
    legs_rise: np.ndarray

    @property
    def upright(self) -> np.ndarray:
        """(T,) bool: the head above the hips above the lower foot."""
        return self.head_up & self.hips_up


def _world(skeleton: Skeleton, rotations: np.ndarray) -> np.ndarray:
    """(T, J, 3, 3) local rotations -> world rotations."""
    world = np.empty_like(rotations)
    for j, p in enumerate(skeleton.parents):
        world[:, j] = rotations[:, j] if p < 0 else world[:, p] @ rotations[:, j]
    return world


def measure_pose(motion: Motion, skeleton: Skeleton, floor_height: float) -> PoseMeasures:
    """Per-frame measures of a motion on the avatar (see the module's docstring).

    Args:
        motion: a motion on ``skeleton``'s joints.
        skeleton: the avatar's skeleton.
        floor_height: the avatar's root above its soles at rest (``Avatar.floor_height``).
    """
    rot = motion.rotations.astype(np.float64)  # (T, J, 3, 3)
    world = _world(skeleton, rot)
    heads = skeleton.heads.astype(np.float64)
    pos = np.zeros(rot.shape[:2] + (3,))  # (T, J, 3)
    for j, p in enumerate(skeleton.parents):
        pos[:, j] = (
            motion.root_translation if p < 0 else pos[:, p] + world[:, p] @ (heads[j] - heads[p])
        )
    names = list(skeleton.names)
    z = pos[..., 2]
    feet = [names.index(n) for n in names if "Foot" in n or "Toe" in n]
    sole = (z[:, feet] - (heads[feet, 2] + floor_height)).min(1)  # (T,)
    lower_foot = z[:, [names.index("LeftFoot"), names.index("RightFoot")]].min(1)
    hips, head = z[:, 0], z[:, names.index("Head")]
    rest_torso = heads[names.index("Head"), 2] - heads[0, 2]  # the head above the hips at rest
    rest_legs = heads[0, 2] - heads[names.index("LeftFoot"), 2]  # the hips above the ankles
    bone = (skeleton.tails - skeleton.heads).astype(np.float64)  # (J, 3)
    rel = rot.copy()
    rel[:, 0] = world[:, 0]
    d = np.einsum("tjab,jb->tja", rel, bone)  # (T, J, 3): bones in their parents' frames
    d /= np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-12)
    cos = np.clip((d[1:] * d[:-1]).sum(-1), -1.0, 1.0)
    turn = np.degrees(np.arccos(cos)) * motion.fps  # (T - 1, J)
    return PoseMeasures(
        head - hips > HEAD_MARGIN * rest_torso,
        hips - lower_foot > STAND_MARGIN * rest_legs,
        sole,
        turn,
        float(motion.fps),
        (head - hips) / rest_torso,
        (hips - lower_foot) / rest_legs,
    )


def _frames(idx: np.ndarray, limit: int = 6) -> str:
    """Frame indices as runs: '12-40, 55, 61-63 (31 frames)'."""
    idx = np.asarray(idx, dtype=np.int64)
    runs, start = [], None
    for k, t in enumerate(idx):
        if start is None:
            start = t
        if k + 1 == len(idx) or idx[k + 1] != t + 1:
            runs.append(f"{start}" if start == t else f"{start}-{t}")
            start = None
    text = ", ".join(runs[:limit]) + (", ..." if len(runs) > limit else "")
    return f"{text} ({len(idx)} frames)"


def pose_problems(measures: PoseMeasures, joint_names: tuple[str, ...]) -> list[str]:
    """What fails the check, one sentence each (empty: the motion passes)."""
    m = measures
    problems = []
    if m.upright.mean() < MIN_UPRIGHT:
        which = [
            f"{what} in frames {_frames(np.flatnonzero(~ok))}"
            for what, ok in (
                ("Head not above Hips", m.head_up),
                ("Hips not above the lower foot (LeftFoot, RightFoot)", m.hips_up),
            )
            if not ok.all()
        ]
        problems.append(
            f"the body does not stand in {1 - m.upright.mean():.0%} of the frames "
            f"(at most {1 - MIN_UPRIGHT:.0%} may): " + "; ".join(which)
        )
    contact = m.sole < CONTACT_M
    if contact.mean() < MIN_CONTACT:
        problems.append(
            f"the feet meet the floor (within {CONTACT_M * 100:g} cm) in "
            f"{contact.mean():.0%} of the frames, at least {MIN_CONTACT:.0%} "
            f"must; they are off it in frames {_frames(np.flatnonzero(~contact))}"
        )
    below = np.flatnonzero(m.sole < -MAX_BELOW_M)
    if len(below):
        problems.append(
            f"a foot is {-m.sole.min():.2f} m below the floor (at most "
            f"{MAX_BELOW_M:g} m) in frames {_frames(below)}"
        )
    fast = m.turn > MAX_TURN_DEG_S
    if fast.any():
        joints = [j for j in np.argsort(-m.turn.max(0)) if fast[:, j].any()]
        worst = ", ".join(
            f"{joint_names[j]} {m.turn[:, j].max() / m.fps:.0f} degrees at frame "
            f"{int(np.argmax(m.turn[:, j]))}"
            for j in joints[:4]
        )
        problems.append(
            f"bones turn faster than a joint can (more than "
            f"{MAX_TURN_DEG_S / m.fps:.0f} degrees in one frame at {m.fps:g} fps, "
            f"{MAX_TURN_DEG_S:g} deg/s): {worst}, in frames "
            f"{_frames(np.flatnonzero(fast.any(1)))}"
        )
    return problems


def check_pose(
    motion: Motion, skeleton: Skeleton, floor_height: float, source: str | None = None
) -> PoseMeasures:
    """Refuse a motion no dancer could dance (see the module's docstring).

    Args:
        motion: a motion on the avatar's joints.
        skeleton: the avatar's skeleton.
        floor_height: ``Avatar.floor_height``.
        source: the file it came from, for the message (default: the motion's name).

    Returns:
        The measures, when it passes.

    Raises:
        LoosefitInputError: naming the source, the frames and the joints that fail.
    """
    measures = measure_pose(motion, skeleton, floor_height)
    problems = pose_problems(measures, tuple(skeleton.names))
    if problems:
        raise LoosefitInputError(
            source or f"motion '{motion.name}'",
            "poses",
            "a motion a dancer could dance: standing, feet on the floor, joints turning no "
            "faster than a body can",
            "; ".join(problems),
            hint="see what the capture shows beside what the avatar does with `loosefit "
            "inspect-motion FILE --sheet sheet.png`; a wrong joint map or up axis "
            "(--joint-map, a map file's source_up) is the usual cause; "
            "--no-pose-check (RetargetConfig(check_pose=False)) lets it through",
        )
    return measures
