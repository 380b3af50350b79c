"""Dressing the avatar: a skirt fitted to its waist and hips, and a garment carried by the body.

Everything here is in the avatar's rest frame (root joint at the origin, see
:class:`~loosefit.body.avatar.Avatar`) unless a function says otherwise.
"""

from __future__ import annotations

import numpy as np
import torch

from loosefit.body.avatar import Avatar, BodySequence
from loosefit.garment.skirt import SkirtConfig, make_skirt, waist_fit_from_points
from loosefit.types import GarmentTemplate

TORSO_BONES = ("Hips", "LowerBack", "Spine", "LHipJoint", "RHipJoint")
HIP_BONES = TORSO_BONES + ("LeftUpLeg", "RightUpLeg", "LeftLeg", "RightLeg")


def natural_waist_height(avatar: Avatar, step: float = 0.005, band: float = 0.01) -> float:
    """Height (rest frame) of the narrowest torso cross-section between lower back and mid-spine.

    Args:
        avatar: the body.
        step: spacing of the heights tried, metres.
        band: half-thickness of each horizontal slab, metres.
    """
    pts = avatar.rest_vertices[avatar.vertices_of_bones(TORSO_BONES)].double().cpu().numpy()
    heads = dict(zip(avatar.joint_names, avatar.skeleton.heads, strict=True))
    lo, hi = heads["LowerBack"][2], 0.5 * (heads["Spine"][2] + heads["Spine1"][2])
    best, best_w = lo, np.inf
    for z in np.arange(lo, hi, step):
        slab = pts[np.abs(pts[:, 2] - z) <= band]
        if len(slab) < 8:
            continue
        width = np.ptp(slab[:, 0]) + np.ptp(slab[:, 1])
        if width < best_w:
            best, best_w = float(z), width
    return best


def fit_skirt(
    avatar: Avatar, config: SkirtConfig | None = None, waist_offset: float = 0.0
) -> GarmentTemplate:
    """A skirt whose waistband fits the avatar's natural waist and whose rest shape clears its hips.

    Args:
        avatar: the body (rest frame: root joint at the origin).
        config: the skirt's style, length and resolution (default: the CPU A-line).
        waist_offset: metres to move the waistband up (+) or down (-) from the natural waist.

    Returns:
        The :class:`GarmentTemplate` in the avatar's rest frame.
    """
    config = config or SkirtConfig.preset("cpu", "aline")
    height = natural_waist_height(avatar) + waist_offset
    pts = avatar.rest_vertices[avatar.vertices_of_bones(HIP_BONES)].double().cpu().numpy()
    fit = waist_fit_from_points(
        pts, height, max_radius=0.3, profile_depth=min(config.length, 0.6), profile_rows=24
    )
    skirt = make_skirt(config, fit)
    skirt.meta["waist_height_rest_frame"] = height
    return skirt


def carry_rigidly(
    template: GarmentTemplate, body: BodySequence, avatar: Avatar, joint: str = "Hips"
) -> torch.Tensor:
    """The garment moved rigidly with one joint: no cloth dynamics at all.

    This is what the demo shows before a simulation exists; it is also a
    baseline for what physics and learning must improve on.

    Args:
        template: the garment at the avatar's rest pose.
        body: the posed body (its ``joint_transforms`` map rest to posed).
        avatar: the avatar that ``body`` was posed with.
        joint: the joint the garment follows.

    Returns:
        (T, V, 3) garment vertices.
    """
    j = avatar.joint_names.index(joint)
    M = body.joint_transforms[:, j]  # (T, 4, 4)
    v = torch.from_numpy(template.vertices).to(M)
    return (M[:, None, :3, :3] @ v[None, :, :, None])[..., 0] + M[:, None, :3, 3]


def garment_for(spec: str, avatar: Avatar, resolution: str = "cpu",
                length: float | None = None) -> GarmentTemplate | None:  # fmt: skip
    """A garment on the avatar's rest pose from a skirt style name or an OBJ file.

    Args:
        spec: ``aline``, ``flared``, ``circle`` (fitted to the avatar), an ``.obj`` path
            (imported as it is), or ``none`` (no garment: None).
        avatar: the body.
        resolution: the skirt's mesh preset (``cpu`` 2,352 vertices, ``paper``).
        length: the skirt's length in metres (default: the style's).

    Raises:
        LoosefitInputError: another spec.
    """
    from loosefit.errors import LoosefitInputError
    from loosefit.garment.skirt import STYLES

    if spec == "none":
        return None
    if spec in STYLES:
        extra = {} if length is None else {"length": length}
        return fit_skirt(avatar, SkirtConfig.preset(resolution, spec, **extra))
    if str(spec).lower().endswith(".obj"):
        from loosefit.garment.obj import load_garment_obj

        return load_garment_obj(spec)
    raise LoosefitInputError("garment", "value", f"one of {STYLES}, 'none' or an .obj",
                             repr(spec))  # fmt: skip
