"""A trained set on a body it was not trained on: the garment carried from the training
body onto another anny body, then fitted to it.

The motion stage runs on the body it knows (the training body, the motion's root scaled
to its legs); each frame's garment is then carried onto the other body posed alike by the
two bodies' own difference, diffused from the skin to the cloth (:func:`carry_garment`:
each garment vertex moves as the skin nearest it moves between the two bodies, as
Santesteban et al. 2019's diffused body model carries skinning away from the surface),
and the other body's garment's own size added (the same pattern sized to that body's waist
and hips, less the trained garment carried at rest, turned with the pelvis); the
edge-length stage then brings the cloth to that garment's rest lengths, and collision
handling runs against that body.

:class:`OtherBody` holds what is prepared once per body; :class:`BodyCarryStage` is the
carry as a stage of a rollout (:mod:`loosefit.inference.stages`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import torch

from loosefit.errors import LoosefitInputError
from loosefit.types import GarmentTemplate, Motion


@dataclass(frozen=True)
class CarryConfig:
    """How the body's difference is diffused to the garment."""

    anchors: int = 256  # skin points (arms left out) whose difference is carried
    reach: float = 0.25  # m: the anchors lie on the skin within this of the garment at rest
    neighbours: int = 8  # anchors each garment vertex takes its displacement from
    rebind: int = 4  # frames between searches for each vertex's nearest anchors
    width: float = 0.04  # m: a neighbour's weight falls off over this beyond the nearest's


def nearest_anchors(
    garment: torch.Tensor, anchors: torch.Tensor, config: CarryConfig = CarryConfig()
) -> torch.Tensor:
    """(n, V, k) the ``config.neighbours`` anchors nearest each garment vertex, found every
    ``config.rebind`` frames and kept for the frames between (the first frame's for the
    first ``rebind``).

    Args:
        garment: (n, V, 3) garment vertices.
        anchors: (n, A, 3) skin anchor points of the same frames.
    """
    k = min(config.neighbours, anchors.shape[1])
    found = [
        torch.topk(torch.cdist(garment[s], anchors[s]), k, dim=-1, largest=False).indices
        for s in range(0, len(garment), config.rebind)
    ]
    return torch.stack(found).repeat_interleave(config.rebind, 0)[: len(garment)]


def carry_weights(
    garment: torch.Tensor, anchors: torch.Tensor, idx: torch.Tensor, width: float
) -> torch.Tensor:
    """(n, V, k) how much each garment vertex follows each of its anchors ``idx`` (n, V, k):
    exp(-((d - d_nearest) / width)^2) of the distance d, normalised (each row sums to 1, the
    nearest weighs most, an anchor a few widths farther than it nothing)."""
    near = anchors[torch.arange(len(anchors))[:, None, None], idx]  # (n, V, k, 3)
    d = torch.linalg.vector_norm(near - garment[:, :, None], dim=-1)
    w = torch.exp(-(((d - d.min(-1, keepdim=True).values) / width) ** 2))
    return w / w.sum(-1, keepdim=True)


def carry_garment(
    garment: torch.Tensor,
    anchors_from: torch.Tensor,
    anchors_to: torch.Tensor,
    config: CarryConfig = CarryConfig(),
) -> torch.Tensor:
    """The garment carried from one body to another posed alike.

    Args:
        garment: (n, V, 3) garment vertices on the first body.
        anchors_from: (n, A, 3) skin anchors of the first body.
        anchors_to: (n, A, 3) the same anchors on the second body.
        config: how the difference is diffused (:func:`nearest_anchors`,
            :func:`carry_weights`).

    Returns:
        (n, V, 3): each vertex moved by the weighted displacement of its nearest anchors.
    """
    idx = nearest_anchors(garment, anchors_from, config)
    w = carry_weights(garment, anchors_from, idx, config.width)
    delta = anchors_to - anchors_from  # (n, A, 3)
    moved = delta[torch.arange(len(delta))[:, None, None], idx]  # (n, V, k, 3)
    return garment + (w[..., None] * moved).sum(2)


def anchor_indices(
    avatar, count: int, garment: np.ndarray | None = None, reach: float = 0.25
) -> torch.Tensor:
    """(A,) body vertices spread evenly (farthest points) over the skin, arms left out (and,
    with ``garment`` (V, 3) at rest, within ``reach`` of it): the anchors of
    :func:`carry_garment`, the same indices on every body of anny's mesh."""
    from scipy.spatial import cKDTree

    from loosefit.body.avatar import ARM_BONES, farthest_point_sampling

    bones = tuple(b for b in avatar.joint_names if b not in ARM_BONES)
    candidates = avatar.vertices_of_bones(bones)
    pts = avatar.rest_vertices[candidates].double().cpu()
    if garment is not None:
        near = cKDTree(np.asarray(garment, np.float64)).query(pts.numpy())[0] <= reach
        if near.sum() >= count:
            candidates, pts = candidates[torch.from_numpy(near)], pts[torch.from_numpy(near)]
    start = int(pts.norm(dim=-1).argmin())
    return candidates[farthest_point_sampling(pts, count, start).to(candidates.device)]


def leg_length(avatar) -> float:
    """Hip to knee to ankle of the avatar's left leg at rest, in metres."""
    heads, names = avatar.skeleton.heads, avatar.skeleton.names
    hip, knee, foot = (heads[names.index(n)] for n in ("LeftUpLeg", "LeftLeg", "LeftFoot"))
    return float(np.linalg.norm(knee - hip) + np.linalg.norm(foot - knee))


def motion_on(motion: Motion, source, target) -> Motion:
    """``motion`` (on ``source``) for ``target``: the same joint rotations, the root's path
    scaled by the ratio of their legs, its height kept above the floor as the legs scale
    (as a capture is retargeted to a body: :mod:`loosefit.motion.retarget`)."""
    scale = leg_length(target) / leg_length(source)
    root = np.asarray(motion.root_translation, np.float64).copy()
    root[:, :2] *= scale
    root[:, 2] = target.floor_height + (root[:, 2] - source.floor_height) * scale
    return Motion(
        joint_names=motion.joint_names,
        rotations=motion.rotations,
        root_translation=root,
        fps=motion.fps,
        name=motion.name,
        meta=dict(motion.meta),
    )


def carried_at_rest(template: GarmentTemplate, trained, avatar, anchors, config: CarryConfig):
    """(V, 3) the garment at rest carried from the ``trained`` body onto ``avatar``
    (:func:`carry_garment` on the rest poses, through the skin points ``anchors``)."""
    return carry_garment(
        torch.as_tensor(template.vertices, dtype=torch.float32)[None],
        trained.rest_vertices[anchors].float().cpu()[None],
        avatar.rest_vertices[anchors].float().cpu()[None],
        config,
    )[0]


def sized_garment(template: GarmentTemplate, trained, avatar, config: CarryConfig, carried=None):
    """The trained set's garment on ``avatar``: a parametric skirt or dress made again from
    its recorded pattern for that body (its own waist, hips or chest), any other garment
    carried at rest from the ``trained`` body (``carried``, :func:`carried_at_rest`, found
    here when not given)."""
    from loosefit.fitting.place import fit_dress, fit_skirt
    from loosefit.garment.dress import DressConfig
    from loosefit.garment.skirt import SkirtConfig

    recorded = template.meta.get("config") if isinstance(template.meta, dict) else None
    if isinstance(recorded, dict) and template.meta.get("kind") == "dress":
        return fit_dress(avatar, DressConfig(**recorded))
    if isinstance(recorded, dict) and "rings" in recorded:
        return fit_skirt(avatar, SkirtConfig(**recorded))
    if carried is None:
        idx = anchor_indices(trained, config.anchors, template.vertices, config.reach)
        carried = carried_at_rest(template, trained, avatar, idx, config)
    return GarmentTemplate(
        vertices=carried.numpy(),
        faces=template.faces,
        uvs=template.uvs,
        face_uvs=template.face_uvs,
        waist=template.waist,
        name=template.name,
        meta=dict(template.meta),
        rest_vertices=template.rest_vertices,
    )


@dataclass
class OtherBody:
    """A body the trained set animates on without having been trained on it: everything
    prepared once (:meth:`prepare`).

    Attributes:
        shape: the body's anny phenotype (all six values).
        avatar: the body.
        trained: the body the set was trained on.
        template: the garment sized to the body (:func:`sized_garment`).
        anchors: (A,) the skin points the carry follows.
        sizing: (V, 3) what the carry leaves of the garment's own size at rest: this body's
            garment less the trained one carried onto it, in the rest pose's frame (zero for
            a garment carried at rest).
        config: how the carry diffuses.
    """

    shape: dict
    avatar: object
    trained: object
    template: GarmentTemplate
    anchors: torch.Tensor
    sizing: torch.Tensor
    config: CarryConfig = field(default_factory=CarryConfig)
    restorer: object = None  # the edge-length stage on its garment, built on first use
    handler: object = None  # collision handling of its garment, built on first use

    @classmethod
    def prepare(
        cls, shape: dict, trained, template: GarmentTemplate, config: CarryConfig = CarryConfig()
    ) -> OtherBody:
        """The body of ``shape`` (anny's phenotype names, each in [0, 1]; those not given
        as the trained body's), beside the ``trained`` avatar and its garment.

        Raises:
            LoosefitInputError: a phenotype name anny does not have, or a value outside
                [0, 1].
        """
        from loosefit.body.avatar import Avatar, AvatarConfig

        if not isinstance(shape, dict):
            raise LoosefitInputError(
                "shape", "shape", "a dict of anny phenotype names to values", type(shape)
            )
        unknown = sorted(str(k) for k in shape if k not in trained.shape)
        if unknown:
            raise LoosefitInputError(
                "shape",
                ", ".join(unknown),
                f"anny's phenotype names: {', '.join(trained.shape)}",
                "unknown names",
            )
        full = {**trained.shape, **{str(k): _value(k, v) for k, v in shape.items()}}
        avatar = Avatar(AvatarConfig(rig=trained.config.rig, shape=full))
        anchors = anchor_indices(trained, config.anchors, template.vertices, config.reach)
        carried = carried_at_rest(template, trained, avatar, anchors, config)
        garment = sized_garment(template, trained, avatar, config, carried)
        if garment.num_vertices != template.num_vertices:  # a pattern that meshes per body
            raise LoosefitInputError(
                "shape",
                "garment",
                f"{template.num_vertices} vertices (the trained garment's) on that body",
                garment.num_vertices,
            )
        sizing = torch.as_tensor(garment.vertices, dtype=torch.float32) - carried
        return cls(dict(avatar.shape), avatar, trained, garment, anchors, sizing, config)

    def trained_motion(self, motion: Motion) -> Motion:
        """``motion`` (on this body) for the body the set was trained on."""
        return motion_on(motion, self.avatar, self.trained)

    def anchors_along(self, avatar, motion: Motion, start: int, stop: int) -> torch.Tensor:
        """(stop - start, A, 3) the anchors of ``avatar`` posed by ``motion``'s frames."""
        rot = torch.from_numpy(motion.rotations[start:stop])
        root = torch.from_numpy(np.asarray(motion.root_translation[start:stop]))
        return avatar.pose(rot, root).vertices[:, self.anchors].float().cpu()


def _value(name, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise LoosefitInputError("shape", str(name), "a number in [0, 1]", repr(value)) from None
    if not 0.0 <= v <= 1.0:
        raise LoosefitInputError("shape", str(name), "a value in [0, 1]", repr(value))
    return v


class BodyCarryStage:
    """The garment carried from the trained body onto the other body, a run of frames at a
    time (the first stage after the detail stage): :func:`carry_garment`, plus the body's
    garment's own size (:attr:`OtherBody.sizing`) turned as the pelvis turns.

    Args:
        body: the other body.
        trained_motion: the motion the rollout runs, on the trained body.
        motion: the same motion on the other body.
    """

    name = "body"

    def __init__(self, body: OtherBody, trained_motion: Motion, motion: Motion) -> None:
        self.body, self.trained_motion, self.motion = body, trained_motion, motion

    def __call__(self, frames) -> torch.Tensor:
        """(n, V, 3) world garments on the other body."""
        s, e = frames.start, frames.start + len(frames.vertices)
        b = self.body
        carried = carry_garment(
            frames.vertices.float(),
            b.anchors_along(b.trained, self.trained_motion, s, e),
            b.anchors_along(b.avatar, self.motion, s, e),
            b.config,
        )
        pelvis = torch.from_numpy(self.motion.rotations[s:e, 0]).float()  # (n, 3, 3)
        return carried + torch.einsum("nij,vj->nvi", pelvis, b.sizing)
