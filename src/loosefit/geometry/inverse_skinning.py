"""Inverse skinning of garments by body seed points (paper 3.2, Eq. 4).

The ground truth unposed garment ``T~_t`` of the paper is approximated by
undoing a linear blend skinning whose "bones" are ``m`` seed points on the
body: each seed point ``j`` has a rigid frame ``{R_j, t_j}`` per frame (rest ->
posed, :meth:`loosefit.body.avatar.Avatar.seed_frames`) and each garment vertex
``i`` a weight ``w_ij``, a softmax of minus its distance to the seed points in
the canonical pose.

Every position here (garment template, seed points) is in the canonical frame
of the seed frames: the avatar's rest pose with the root joint at the origin.
All functions are pure, batched and differentiable, in float32 or float64.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from loosefit.errors import LoosefitInputError


@dataclass
class InverseSkinningConfig:
    """How unposed garment targets are computed."""

    num_seeds: int = 256  # m, seed points sampled on the lower body (Avatar.seed_points)
    temperature: float = 0.05  # metres; softmax of -distance / temperature (Eq. 4 has 1)


def _check_shape(
    source: str, field: str, x: torch.Tensor, expected: tuple[int | None, ...]
) -> None:
    """Raise unless ``x`` has ``len(expected)`` dims matching it (None: any size)."""
    ok = x.ndim == len(expected) and all(
        e is None or s == e for s, e in zip(x.shape, expected, strict=True)
    )
    if not ok:
        shape = ", ".join(str(e) if e is not None else "?" for e in expected)
        raise LoosefitInputError(source, field, f"shape ({shape})", f"{tuple(x.shape)}")


def seed_weights(
    canonical_vertices: torch.Tensor, seed_rest: torch.Tensor, temperature: float = 0.05
) -> torch.Tensor:
    """Skinning weights of garment vertices on body seed points (paper Eq. 4).

    ``w_ij = softmax_j(-d(i, j) / temperature)`` with ``d`` the Euclidean
    distance between garment vertex ``i`` and seed point ``j``, both in the
    canonical pose. The paper writes ``exp(-d)`` with no scale; our distances
    are in metres, where ``exp(-d)`` is nearly uniform over a body (every seed
    within ~1 m), so ``temperature`` (metres) sets how local the weights are:
    they fall by a factor ``e`` per ``temperature`` of extra distance, and
    ``temperature = 1`` is the paper's formula.

    Args:
        canonical_vertices: (..., V, 3) garment vertices in the canonical pose.
        seed_rest: (m, 3) or (..., m, 3) seed points at the rest pose
            (batch dims broadcast with the vertices').
        temperature: softmax scale in metres, > 0.

    Returns:
        (..., V, m) weights, each row summing to 1.
    """
    if not temperature > 0:
        raise LoosefitInputError(
            "seed_weights", "temperature", "a positive float", repr(temperature)
        )
    if canonical_vertices.ndim < 2 or canonical_vertices.shape[-1] != 3:
        raise LoosefitInputError(
            "seed_weights",
            "canonical_vertices",
            "shape (..., V, 3)",
            f"{tuple(canonical_vertices.shape)}",
        )
    if seed_rest.ndim < 2 or seed_rest.shape[-1] != 3:
        raise LoosefitInputError(
            "seed_weights", "seed_rest", "shape (m, 3) or (..., m, 3)", f"{tuple(seed_rest.shape)}"
        )
    # Exact differences, not the |x|^2 - 2xy + |y|^2 matmul form (cancellation near 0).
    d = torch.cdist(
        canonical_vertices,
        seed_rest.to(canonical_vertices),
        compute_mode="donot_use_mm_for_euclid_dist",
    )  # (..., V, m)
    return torch.softmax(-d / temperature, dim=-1)


def blend_frames(
    weights: torch.Tensor, R: torch.Tensor, t: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """Per-vertex blended affine transforms ``A_i = sum_j w_ij [R_j | t_j]``.

    Args:
        weights: (B or 1, V, m).
        R: (B, m, 3, 3) seed rotations (rest -> posed).
        t: (B, m, 3) seed translations.

    Returns:
        M (B, V, 3, 3) = ``sum_j w_ij R_j`` and b (B, V, 3) = ``sum_j w_ij t_j``.
    """
    _check_shape("blend_frames", "R", R, (None, None, 3, 3))
    B, m = R.shape[:2]
    _check_shape("blend_frames", "t", t, (B, m, 3))
    if weights.ndim != 3 or weights.shape[0] not in (1, B) or weights.shape[2] != m:
        raise LoosefitInputError(
            "blend_frames", "weights", f"shape ({B} or 1, V, {m})", f"{tuple(weights.shape)}"
        )
    M = torch.einsum("bvm,bmij->bvij", weights.expand(B, -1, -1), R)  # (B, V, 3, 3)
    b = weights @ t  # (B, V, 3)
    return M, b


def _check_points(source: str, field: str, x: torch.Tensor, B: int, V: int) -> None:
    if x.ndim != 3 or x.shape[0] not in (1, B) or x.shape[1:] != (V, 3):
        raise LoosefitInputError(source, field, f"shape ({B}, {V}, 3)", f"{tuple(x.shape)}")


def skin(
    canonical: torch.Tensor, weights: torch.Tensor, R: torch.Tensor, t: torch.Tensor
) -> torch.Tensor:
    """Forward linear blend skinning ``x_i = sum_j w_ij (R_j c_i + t_j)``.

    Args:
        canonical: (B, V, 3) vertices in the canonical pose (batch 1 broadcasts).
        weights: (B or 1, V, m) rows summing to 1.
        R: (B, m, 3, 3) seed rotations (rest -> posed).
        t: (B, m, 3) seed translations.

    Returns:
        (B, V, 3) posed vertices.
    """
    M, b = blend_frames(weights, R, t)  # (B, V, 3, 3), (B, V, 3)
    _check_points("skin", "canonical", canonical, M.shape[0], M.shape[1])
    return (M @ canonical[..., None])[..., 0] + b


def unskin(
    posed: torch.Tensor, weights: torch.Tensor, R: torch.Tensor, t: torch.Tensor
) -> torch.Tensor:
    """Inverse linear blend skinning: the canonical ``c_i`` that :func:`skin` maps to ``p_i``.

    With ``M_i = sum_j w_ij R_j`` and ``b_i = sum_j w_ij t_j``, solves
    ``M_i c_i = p_i - b_i`` per vertex (batched ``torch.linalg.solve``), so
    ``skin(unskin(p, w, R, t), w, R, t) == p`` up to rounding. ``M_i`` is a
    convex blend of rotations: invertible unless the seeds that weigh on a
    vertex turn by nearly opposite rotations (then the result is ill-conditioned).

    Args:
        posed: (B, V, 3) posed vertices (batch 1 broadcasts).
        weights: (B or 1, V, m) rows summing to 1.
        R: (B, m, 3, 3) seed rotations (rest -> posed).
        t: (B, m, 3) seed translations.

    Returns:
        (B, V, 3) vertices in the canonical pose.
    """
    M, b = blend_frames(weights, R, t)  # (B, V, 3, 3), (B, V, 3)
    _check_points("unskin", "posed", posed, M.shape[0], M.shape[1])
    return torch.linalg.solve(M, (posed - b)[..., None])[..., 0]  # (B, V, 3)


def unposed_targets(
    posed: torch.Tensor,
    template: torch.Tensor,
    seed_rest: torch.Tensor,
    R: torch.Tensor,
    t: torch.Tensor,
    temperature: float = InverseSkinningConfig.temperature,
) -> torch.Tensor:
    """Approximate unposed garments ``T~_t`` from posed ones (paper 3.2).

    The paper computes per-frame weights ``W_t`` from the unposed mesh ``T~_t``
    itself, which is the unknown. We take the canonical shape to be the
    garment template at rest, so the weights (:func:`seed_weights` of the
    template) are the same for every frame and computed once per call; callers
    with many batches can compute them once with :func:`seed_weights` and call
    :func:`unskin` directly.

    Args:
        posed: (B, V, 3) simulated garments (B frames).
        template: (V, 3) the garment at rest in the canonical pose.
        seed_rest: (m, 3) seed points at the rest pose (``SeedPoints.rest``).
        R: (B, m, 3, 3) seed rotations of each frame (``Avatar.seed_frames``).
        t: (B, m, 3) seed translations of each frame.
        temperature: softmax scale in metres (see :func:`seed_weights`).

    Returns:
        (B, V, 3) unposed garments in the canonical pose.
    """
    _check_shape("unposed_targets", "template", template, (None, 3))
    _check_shape(
        "unposed_targets", "seed_rest", seed_rest, (R.shape[1] if R.ndim == 4 else None, 3)
    )
    weights = seed_weights(template.to(posed), seed_rest.to(posed), temperature)[None]  # (1, V, m)
    return unskin(posed, weights, R.to(posed), t.to(posed))
