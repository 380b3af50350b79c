"""The avatar's bone rotations from what a motion capture shows, bone by bone.

A capture's zero pose (every rotation channel at zero) is a convention of the rig
that wrote it: a T-pose, an A-pose, or no pose at all (every bone along its own
local X axis, the standing orientation carried by every frame's rotations). What
the capture does show, whatever that convention, is each joint's world position
and orientation at each frame (its forward kinematics). The avatar is posed from
those, bone by bone:

    W_a(t) = Q_b(t) R_a

where ``W_a(t)`` is the world rotation of avatar joint ``a`` from its rest pose,
``Q_b(t)`` the world rotation of the source joint ``b`` that drives it, in the
avatar's axes, and ``R_a`` a constant: the avatar bone's rest frame seen in the
source joint's own frame (its *calibration*). Because ``R_a`` is constant, every
turn of the source joint, its twist included, reaches the avatar bone as it is;
only the calibration has to be found, once per clip, two ways:

* **zero pose** (``reference="zero-pose"``): the source's zero pose is taken to
  stand as the avatar's rest does. Limbs (``align``): ``R_a`` is the smallest
  rotation taking the avatar bone onto the source bone at zero pose; the torso
  (pelvis, spine, neck, head) keeps ``R_a = R_parent``: the two stand alike.
  This is how standing-rest files (CMU, DAZ, Mixamo T-poses) always retargeted.
* **clip** (``reference="clip"``): nothing assumed of the zero pose.
  Limbs: ``R_a`` takes the avatar bone (head to the next mapped joint, or to its
  tail for a hand, foot or toe) onto the source bone's direction *in b's own
  frame* (the child's offset, the same at every frame), and about that axis it
  turns to best match second directions, summed over every frame of the clip
  (Wahba's problem about one axis, each frame weighted by how clearly it shows
  the direction):

  - thigh: where the shin goes (the knee bends in one plane) and where the foot
    points; shin: where the thigh goes and where the foot points;
  - foot and toes: where the shin goes (up);
  - upper arm: where the forearm goes (the elbow bends in one plane); forearm:
    where the upper arm goes;
  - collar and hand, and every limb weakly: the parent's solved frame (the bone
    keeps the avatar's rest twist relative to its parent on average).

  Torso joints: the rigs put them in places too different to match bone by bone
  (the avatar's pelvis bone leans 35 degrees back, a mocap rig's points straight
  up), so ``R_a`` is the rotation that best matches, summed over every frame,
  landmarks every humanoid rig has: the left-right axis between the thighs (the
  pelvis, the lower back), the axis between the upper arms (chest, neck, head),
  the trunk's line from between the thighs to between the upper arms, and the
  head above the shoulders. The dancer's average posture over the clip is taken
  to be the avatar's rest posture, the pelvis's left-right axis is exact.

Finally each limb bone is turned, frame by frame, by the smallest rotation that
puts it exactly along the source's bone at that frame (it already is, unless joints
the map leaves out lie between). :func:`zero_pose_stands` tells which calibration a
clip takes with ``reference="auto"``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from loosefit.body.avatar import Skeleton
from loosefit.geometry.rotations import rotation_between

# Avatar joints calibrated by landmarks (pelvis, spine, neck, head), not bone by bone.
TORSO = ("Hips", "LHipJoint", "RHipJoint", "LowerBack", "Spine", "Spine1", "Neck", "Neck1", "Head")
REFERENCES = ("auto", "zero-pose", "clip")  # what RetargetConfig.reference takes

# A zero pose "stands" when each leg points down and the torso up within this angle of
# the vertical, and the left thigh lies to the left within it (cos 37 deg = 0.8): a
# T-pose, an A-pose, arms down all do; bones along X or Y do not.
STANDING_COS = 0.8


@dataclass(frozen=True)
class SourcePose:
    """A capture's forward kinematics, in the avatar's axes (Z up, facing -Y), metres.

    Attributes:
        positions: (T, Js, 3) world joint positions.
        rotations: (T, Js, 3, 3) world joint rotations (identity at the zero pose).
        parents: (Js,) parent indices, -1 for the root.
        rest: (Js, 3) joint positions at the zero pose.
        leaf: {j: ((T, 3), (3,))} for joints with an End Site or a single child joint:
            its world direction at each frame and at the zero pose.
    """

    positions: np.ndarray
    rotations: np.ndarray
    parents: np.ndarray
    rest: np.ndarray
    leaf: dict[int, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)


@dataclass(frozen=True)
class BoneRotations:
    """The avatar's world rotations and how each bone was calibrated.

    Attributes:
        world: (T, J, 3, 3) world rotation of each avatar joint from its rest pose.
        reference: "zero-pose" or "clip" (see the module's docstring).
        how: avatar joint -> a few words on its calibration, for reports.
    """

    world: np.ndarray
    reference: str
    how: dict[str, str]


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.where(n > 1e-9, v / np.maximum(n, 1e-12), 0.0)


def _local(rot: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(T, 3, 3) world rotations, (T, 3) world vectors -> (T, 3) in the joints' frames."""
    return np.einsum("tji,tj->ti", rot, u)


def _axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    """(3, 3) rotation by ``angle`` radians about the unit ``axis`` (Rodrigues)."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)


def twist_angle(axis: np.ndarray, cues: list[tuple[np.ndarray, np.ndarray, float]]) -> float:
    """The turn about ``axis`` that best carries each ``v`` onto its ``u`` (least squares).

    Args:
        axis: (3,) unit vector.
        cues: (v (3,), u (T, 3), weight): a direction and where it should go at each
            frame. Both are projected off the axis; ``v`` is normalised there, ``u`` is
            normalised before, so a frame counts by the sine of its angle to the axis.

    Returns:
        The angle in radians about ``axis`` (right hand), 0 when no cue leaves the axis.
    """
    num = den = 0.0
    for v, u, w in cues:
        v_p = v - (v @ axis) * axis
        if np.linalg.norm(v_p) < 1e-6:
            continue
        v_p = v_p / np.linalg.norm(v_p)
        u = _unit(u)
        u_p = u - (u @ axis)[:, None] * axis  # (T, 3)
        num += w * float(np.cross(v_p, u_p).sum(0) @ axis)
        den += w * float((u_p @ v_p).sum())
    return float(np.arctan2(num, den)) if np.hypot(num, den) > 1e-9 else 0.0


def best_rotation(cues: list[tuple[np.ndarray, np.ndarray, float]]) -> np.ndarray | None:
    """The rotation R that best carries each ``v`` onto its ``u`` (Wahba's problem).

    Args:
        cues: (v (3,), u (T, 3), weight); both normalised per frame.

    Returns:
        (3, 3) R minimising the weighted sum of ``|u_t - R v|^2``, or None when the
        cues span less than two directions.
    """
    B = np.zeros((3, 3))
    for v, u, w in cues:
        B += w * np.einsum("ti,j->ij", _unit(u), _unit(v[None])[0])
    U, S, Vt = np.linalg.svd(B)
    if S[1] < 1e-6 * max(S[0], 1e-12):
        return None
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    return U @ D @ Vt


def zero_pose_stands(rest: np.ndarray, present: dict[str, int]) -> tuple[bool, str]:
    """Whether a source's zero pose stands as the avatar's rest does, and why not.

    Args:
        rest: (Js, 3) source joint positions at the zero pose, avatar axes.
        present: avatar joint -> source joint index.

    Returns:
        (True, "") or (False, what fails): a leg that does not point down, a torso that
        does not point up, a left thigh not on the left (cosines below STANDING_COS).
    """

    def cos(a: str, b: str, axis: int, sign: float = 1.0) -> float | None:
        if a not in present or b not in present:
            return None
        d = rest[present[b]] - rest[present[a]]
        n = np.linalg.norm(d)
        return float(sign * d[axis] / n) if n > 1e-9 else None

    checks = {
        "the left leg points down": cos("LeftUpLeg", "LeftFoot", 2, -1),
        "the right leg points down": cos("RightUpLeg", "RightFoot", 2, -1),
        "the torso points up": cos(
            "Hips", next((a for a in ("Head", "Neck", "Spine1") if a in present), "Head"), 2
        ),
        "the left thigh is on the left": cos("RightUpLeg", "LeftUpLeg", 0),
    }
    fails = [what for what, c in checks.items() if c is None or c < STANDING_COS]
    return (not fails, "not: " + ", ".join(fails) if fails else "")


def _chain_child(skeleton: Skeleton, a: int, mapped: set[str]) -> int | None:
    """The first mapped avatar joint down a's chain (the child nearest a's tail, then on)."""
    names = skeleton.names
    subtree_mapped = {}

    def has_mapped(j: int) -> bool:
        if j not in subtree_mapped:
            subtree_mapped[j] = names[j] in mapped or any(
                has_mapped(c) for c in skeleton.children(j)
            )
        return subtree_mapped[j]

    j = a
    while True:
        kids = skeleton.children(j)
        if not kids:
            return None
        c = min(kids, key=lambda c: np.linalg.norm(skeleton.heads[c] - skeleton.tails[j]))
        if not has_mapped(c):
            return None
        if names[c] in mapped:
            return c
        j = c


def _is_below(parents: np.ndarray, b: int, ancestor: int) -> bool:
    while b >= 0:
        b = int(parents[b])
        if b == ancestor:
            return True
    return False


# A cue: (avatar rest vector (3,), source world vectors (T, 3)); None when a joint is unmapped.
_Pair = tuple[np.ndarray, np.ndarray]


@dataclass(frozen=True)
class _Landmarks:
    """Vectors between mapped joints, on the avatar at rest and in the capture.

    Attributes:
        names: the avatar's J joint names.
        heads, tails: (J, 3) float64 avatar bone heads and tails at rest.
        positions: (T, Js, 3) float64 source world joint positions.
        present: avatar joint -> source joint index.
        leaf: the source's End Site directions (:attr:`SourcePose.leaf`).
    """

    names: tuple[str, ...]
    heads: np.ndarray
    tails: np.ndarray
    positions: np.ndarray
    present: dict[str, int]
    leaf: dict[int, tuple[np.ndarray, np.ndarray]]

    def src(self, a: str) -> np.ndarray | None:
        """(T, 3) world positions of the source joint driving ``a``."""
        return self.positions[:, self.present[a]] if a in self.present else None

    def pair(self, a1: str, a2: str) -> _Pair | None:
        """(avatar rest vector, source vectors (T, 3)) from joint a1 to joint a2."""
        if a1 not in self.present or a2 not in self.present:
            return None
        h = self.heads
        return h[self.names.index(a2)] - h[self.names.index(a1)], self.src(a2) - self.src(a1)

    def mid_pair(self, a1: str, a2: str, b1: str, b2: str) -> _Pair | None:
        """From the midpoint of a1, a2 to the midpoint of b1, b2."""
        if not {a1, a2, b1, b2} <= set(self.present):
            return None
        h = {n: self.heads[self.names.index(n)] for n in (a1, a2, b1, b2)}
        src = self.src
        return ((h[b1] + h[b2] - h[a1] - h[a2]) / 2, (src(b1) + src(b2) - src(a1) - src(a2)) / 2)

    def foot_forward(self, S: str) -> _Pair | None:
        """Where side ``S``'s foot points: to its toe, else along its End Site."""
        toe = self.pair(f"{S}Foot", f"{S}ToeBase")
        if toe is not None or f"{S}Foot" not in self.present:
            return toe
        f = self.names.index(f"{S}Foot")
        leaf = self.leaf.get(self.present[f"{S}Foot"])
        return (self.tails[f] - self.heads[f], leaf[0]) if leaf is not None else None

    def limb_cues(self, an: str) -> list[tuple[_Pair | None, float]]:
        """The second directions (and weights) that set limb ``an``'s twist."""
        S = "Left" if an.startswith("Left") else "Right"
        bone = an.removeprefix(S)
        pair = self.pair
        return {
            "UpLeg": [(pair(f"{S}Leg", f"{S}Foot"), 1.0), (self.foot_forward(S), 0.5)],
            "Leg": [(pair(f"{S}Leg", f"{S}UpLeg"), 1.0), (self.foot_forward(S), 0.5)],
            "Foot": [(pair(f"{S}Foot", f"{S}Leg"), 1.0)],
            "ToeBase": [(pair(f"{S}Foot", f"{S}Leg"), 1.0)],
            "Arm": [(pair(f"{S}ForeArm", f"{S}Hand"), 1.0)],
            "ForeArm": [(pair(f"{S}ForeArm", f"{S}Arm"), 1.0)],
        }.get(bone, [])

    def torso_cues(self) -> dict[str, list[tuple[_Pair | None, float]]]:
        """Avatar torso joint -> [(landmark, weight)]: the hips' and arms' left-right
        axes, the trunk's line and the head above the shoulders."""
        mapped = set(self.present)
        arms = (
            ("LeftArm", "RightArm")
            if {"LeftArm", "RightArm"} <= mapped
            else ("LeftShoulder", "RightShoulder")
        )
        lat_hips = self.pair("RightUpLeg", "LeftUpLeg")
        lat_arms = self.pair(arms[1], arms[0])
        trunk = self.mid_pair("LeftUpLeg", "RightUpLeg", *arms)
        head_up = self.mid_pair(*arms, "Head", "Head")
        return {
            **dict.fromkeys(("Hips", "LHipJoint", "RHipJoint"), [(lat_hips, 1.0), (trunk, 1.0)]),
            "LowerBack": [(lat_hips, 0.67), (lat_arms, 0.33), (trunk, 1.0)],
            "Spine": [(lat_hips, 0.33), (lat_arms, 0.67), (trunk, 1.0)],
            "Spine1": [(lat_arms, 1.0), (trunk, 1.0)],
            **dict.fromkeys(("Neck", "Neck1", "Head"), [(lat_arms, 1.0), (head_up, 1.0)]),
        }


def _primary_bone(
    skeleton: Skeleton, source: SourcePose, landmarks: _Landmarks, a: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Limb ``a``'s bone: (avatar rest vector (3,), source world vectors (T, 3), source
    vector at zero pose (3,)), to the next mapped joint down the chain, else along the
    End Site or only child; None when there is none or it has no length."""
    names, present = skeleton.names, landmarks.present
    heads, tails, P = landmarks.heads, landmarks.tails, landmarks.positions  # P: (T, Js, 3)
    b = present[names[a]]
    primary = None
    c = _chain_child(skeleton, a, set(present))
    if c is not None and _is_below(source.parents, present[names[c]], b):
        sc = present[names[c]]
        primary = (heads[c] - heads[a], P[:, sc] - P[:, b], source.rest[sc] - source.rest[b])
    elif c is None and b in source.leaf:
        primary = (tails[a] - heads[a], *source.leaf[b])
    if primary is not None and min(np.linalg.norm(primary[0]), np.linalg.norm(primary[2])) < 1e-9:
        primary = None
    return primary


def _clip_limb_calibration(
    an: str,
    Qb: np.ndarray,
    primary: tuple[np.ndarray, np.ndarray, np.ndarray],
    parent_cues: list[tuple[np.ndarray, np.ndarray, float]],
    landmarks: _Landmarks,
) -> tuple[np.ndarray, str]:
    """A limb's (3, 3) R_a from the whole clip, and how: its bone's direction in the
    source joint's frame (``Qb``, (T, 3, 3)), turned about it to match the bend."""
    local = _unit(_local(Qb, primary[1]))  # (T, 3): the bone in b's frame
    axis = _unit(local.mean(0)[None])[0]
    if np.linalg.norm(axis) < 0.5:
        axis = _unit(primary[2][None])[0]
    R0 = rotation_between(primary[0][None], axis[None])[0].astype(np.float64)
    cues = [
        (R0 @ v, _local(Qb, u), w)
        for (v, u), w in ((c, w) for c, w in landmarks.limb_cues(an) if c is not None)
    ]
    main = bool(cues)
    cues += [(R0 @ v, _local(Qb, u), 0.1 if main else 1.0) for v, u, _ in parent_cues]
    how = "bone and " + ("bend" if main else "its parent's twist")
    return _axis_angle(axis, twist_angle(axis, cues)) @ R0, how


def _torso_calibration(
    Qb: np.ndarray,
    cues_of_joint: list[tuple[_Pair | None, float]],
    parent_cues: list[tuple[np.ndarray, np.ndarray, float]],
    has_parent: bool,
) -> tuple[np.ndarray, str]:
    """A torso joint's (3, 3) R_a from landmarks over the clip (else its parent's frame)."""
    cues = [
        (v, _local(Qb, u), w) for (v, u), w in ((c, w) for c, w in cues_of_joint if c is not None)
    ]
    R = best_rotation(cues)
    if R is None and has_parent:  # too few landmarks: the parent's frame
        R = best_rotation([(v, _local(Qb, u), w) for v, u, w in parent_cues])
    how = "landmarks" if cues and R is not None else "its parent"
    return (R if R is not None else np.eye(3)), how


def _along_source(
    world_a: np.ndarray, primary: tuple[np.ndarray, np.ndarray, np.ndarray]
) -> np.ndarray:
    """(T, 3, 3) world rotations turned so the bone lies exactly along the source's."""
    T = len(world_a)
    now = world_a @ primary[0]  # (T, 3)
    ok = np.linalg.norm(primary[1], axis=-1) > 1e-9
    fix = np.tile(np.eye(3), (T, 1, 1))
    if ok.any():
        fix[ok] = rotation_between(now[ok], primary[1][ok]).astype(np.float64)
    return fix @ world_a


def solve_bone_rotations(
    skeleton: Skeleton,
    source: SourcePose,
    present: dict[str, int],
    align: tuple[str, ...],
    reference: str = "auto",
) -> BoneRotations:
    """The avatar's world rotations at every frame of a capture (see the module's docstring).

    Args:
        skeleton: the avatar's skeleton (rest pose: ``heads``, ``tails``).
        source: the capture's forward kinematics in the avatar's axes.
        present: avatar joint -> source joint index, for the joints the map drives.
        align: the limbs matched bone by bone (a joint map's ``align``); other mapped
            joints are torso-like.
        reference: "zero-pose", "clip", or "auto": "zero-pose" when
            :func:`zero_pose_stands`, else "clip".

    Returns:
        The rotations, (T, J, 3, 3), with the reference used. Unmapped avatar joints
        follow their parent rigidly.
    """
    names, parents = skeleton.names, skeleton.parents
    Q = source.rotations.astype(np.float64)  # (T, Js, 3, 3)
    T, J = source.positions.shape[0], len(names)
    if reference == "auto":
        reference = "zero-pose" if zero_pose_stands(source.rest, present)[0] else "clip"
    landmarks = _Landmarks(
        names,
        skeleton.heads.astype(np.float64),
        skeleton.tails.astype(np.float64),
        source.positions.astype(np.float64),
        present,
        source.leaf,
    )
    torso_cues = landmarks.torso_cues()

    world = np.zeros((T, J, 3, 3))
    calib = np.tile(np.eye(3), (J, 1, 1))  # R_a
    how: dict[str, str] = {}
    for a, an in enumerate(names):
        p = parents[a]
        if an not in present:
            world[:, a] = world[:, p] if p >= 0 else np.eye(3)
            calib[a] = calib[p] if p >= 0 else np.eye(3)
            continue
        Qb = Q[:, present[an]]
        parent_world = world[:, p] if p >= 0 else np.broadcast_to(np.eye(3), (T, 3, 3))
        # The parent's frame, as cues: the three axes of the avatar's rest carried by it.
        parent_cues = [(np.eye(3)[k], parent_world[:, :, k], 1.0) for k in range(3)]

        # 1. The bone: the next mapped joint down the chain, else the End Site / only child.
        primary = _primary_bone(skeleton, source, landmarks, a) if an in align else None

        # 2. The calibration R_a.
        if reference == "zero-pose":
            if primary is not None:
                calib[a] = rotation_between(primary[0][None], primary[2][None])[0]
                how[an] = "bone at zero pose"
            else:
                calib[a] = calib[p] if p >= 0 else np.eye(3)
                how[an] = "as its parent at zero pose" if p >= 0 else "zero pose"
        elif primary is not None:
            calib[a], how[an] = _clip_limb_calibration(an, Qb, primary, parent_cues, landmarks)
        else:
            calib[a], how[an] = _torso_calibration(Qb, torso_cues.get(an, []), parent_cues, p >= 0)

        world[:, a] = Qb @ calib[a]
        # 3. The bone exactly along the source's at each frame.
        if primary is not None:
            world[:, a] = _along_source(world[:, a], primary)
    return BoneRotations(world, reference, how)
