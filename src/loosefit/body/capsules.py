"""Capsules fitted to the avatar: the collider an engine keeps for the engine tier.

A capsule is a segment and a radius, attached to a joint: its two end points are given in
the joint's frame, a frame at the joint's head whose axes are the world's at the rest pose
and turn with the joint (:func:`joint_frames`: ``G_j = G_parent T(head_j - head_parent)
R_j``, the rotation the motion gives the joint). Three cover the trunk (the pelvis between
the hip joints, the abdomen, the waist) and three each leg (the thigh in two, the shin),
each fitted to the body vertices skinned to its bones: the radius is the median distance of
those vertices from the segment.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# name: (joint, bones whose vertices it covers, start, end, the share of the segment from
# start to end its vertices are taken along); a point is a joint's head, or "A..B@f", the
# point at f of the way from A's head to B's head
CAPSULE_SPECS: dict[str, tuple[str, tuple[str, ...], str, str]] = {
    "pelvis": ("Hips", ("Hips", "LHipJoint", "RHipJoint"), "LeftUpLeg", "RightUpLeg"),
    "abdomen": ("LowerBack", ("LowerBack",), "LowerBack", "Spine"),
    "waist": ("Spine", ("Spine",), "Spine", "Spine1"),
    "left_thigh_upper": ("LeftUpLeg", ("LeftUpLeg",), "LeftUpLeg", "LeftUpLeg..LeftLeg@0.5"),
    "left_thigh_lower": ("LeftUpLeg", ("LeftUpLeg",), "LeftUpLeg..LeftLeg@0.5", "LeftLeg"),
    "left_shin": ("LeftLeg", ("LeftLeg",), "LeftLeg", "LeftFoot"),
    "right_thigh_upper": ("RightUpLeg", ("RightUpLeg",), "RightUpLeg", "RightUpLeg..RightLeg@0.5"),
    "right_thigh_lower": ("RightUpLeg", ("RightUpLeg",), "RightUpLeg..RightLeg@0.5", "RightLeg"),
    "right_shin": ("RightLeg", ("RightLeg",), "RightLeg", "RightFoot"),
}


@dataclass(frozen=True)
class Capsule:
    """A capsule attached to a joint.

    Attributes:
        name: what it covers.
        joint: the joint it moves with.
        start, end: (3,) its segment's end points in the joint's frame (m).
        radius: m.
    """

    name: str
    joint: str
    start: tuple[float, float, float]
    end: tuple[float, float, float]
    radius: float

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "joint": self.joint,
            "start": list(self.start),
            "end": list(self.end),
            "radius": self.radius,
        }


def _point(spec: str, names: tuple[str, ...], heads: np.ndarray) -> np.ndarray:
    if ".." not in spec:
        return heads[names.index(spec)]
    pair, _, f = spec.partition("@")
    a, b = pair.split("..")
    return (1 - float(f)) * heads[names.index(a)] + float(f) * heads[names.index(b)]


def segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, ...]:
    """Points (N, 3) against the segment a-b (3,): the distance (N,) and where along it the
    nearest point is, t in [0, 1] (N,), before clipping."""
    ab = b - a
    t = (points - a) @ ab / max(float(ab @ ab), 1e-12)
    q = a + np.clip(t, 0, 1)[:, None] * ab
    return np.linalg.norm(points - q, axis=1), t


def fit_capsules(
    names: tuple[str, ...], heads: np.ndarray, vertices: np.ndarray, bone_of: np.ndarray
) -> list[Capsule]:
    """The capsules of :data:`CAPSULE_SPECS` fitted to a body at its rest pose.

    Args:
        names: J joint names.
        heads: (J, 3) the joints' rest positions.
        vertices: (Vb, 3) the body's rest vertices.
        bone_of: (Vb,) each vertex's joint (its largest skinning weight).

    Returns:
        The capsules, their points in their joints' frames.
    """
    out = []
    for name, (joint, bones, s, e) in CAPSULE_SPECS.items():
        a, b = _point(s, names, heads), _point(e, names, heads)
        mine = np.isin(bone_of, [names.index(n) for n in bones])
        d, t = segment_distance(vertices[mine], a, b)
        along = (t >= 0) & (t <= 1)
        radius = float(np.median(d[along] if along.any() else d))
        h = heads[names.index(joint)]
        out.append(Capsule(name, joint, tuple(map(float, a - h)), tuple(map(float, b - h)), radius))
    return out


def avatar_capsules(avatar) -> list[Capsule]:
    """:func:`fit_capsules` of an :class:`~loosefit.body.avatar.Avatar`."""
    sk = avatar.skeleton
    weights = avatar.model.vertex_bone_weights
    indices = avatar.model.vertex_bone_indices.long()
    bone_of = indices.gather(1, weights.argmax(1, keepdim=True))[:, 0].cpu().numpy()
    rest = avatar.rest_vertices.detach().cpu().numpy().astype(np.float64)
    rest = rest.reshape(-1, rest.shape[-2], 3)[0] if rest.ndim == 3 else rest
    return fit_capsules(tuple(sk.names), np.asarray(sk.heads, np.float64), rest, bone_of)


def joint_frames(
    rotations: np.ndarray,
    root: np.ndarray,
    parents: np.ndarray,
    offsets: np.ndarray,
    wanted: list[int] | None = None,
) -> np.ndarray:
    """World frames (B, J, 4, 4) of the joints (rows ``wanted`` and their ancestors filled,
    the rest identity): ``G_root = [R_root, root]``, ``G_j = G_parent T(offset_j) R_j``.

    Args:
        rotations: (B, J, 3, 3) local rotations.
        root: (B, 3) the root's world position.
        parents: (J,) parent indices (-1 for the root), parents before children.
        offsets: (J, 3) each joint's head minus its parent's at rest.
        wanted: the joints needed (default all).
    """
    B, J = rotations.shape[:2]
    need = set(range(J)) if wanted is None else set()
    for j in wanted or []:
        while j >= 0 and j not in need:
            need.add(j)
            j = int(parents[j])
    G = np.broadcast_to(np.eye(4, dtype=rotations.dtype), (B, J, 4, 4)).copy()
    for j in sorted(need):
        p = int(parents[j])
        if p < 0:
            G[:, j, :3, :3], G[:, j, :3, 3] = rotations[:, j], root
        else:
            G[:, j, :3, :3] = G[:, p, :3, :3] @ rotations[:, j]
            G[:, j, :3, 3] = G[:, p, :3, :3] @ offsets[j] + G[:, p, :3, 3]
    return G
