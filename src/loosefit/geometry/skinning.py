"""Linear blend skinning pieces: pure functions over batched tensors."""

from __future__ import annotations

import torch


def blend_transforms(
    transforms: torch.Tensor, weights: torch.Tensor, indices: torch.Tensor
) -> torch.Tensor:
    """Per-point blended skinning matrices ``sum_k w_ik T_{idx_ik}``.

    Args:
        transforms: (T, J, 4, 4) joint skinning transforms (rest -> posed).
        weights: (N, K) skinning weights, rows summing to 1.
        indices: (N, K) joint indices.

    Returns:
        (T, N, 4, 4) blended (generally not rigid) transforms.
    """
    gathered = transforms[:, indices.long()]  # (T, N, K, 4, 4)
    return (weights[None, :, :, None, None] * gathered).sum(2)


def nearest_rotation(matrices: torch.Tensor) -> torch.Tensor:
    """The rotation closest (Frobenius) to each 3x3 matrix (polar decomposition).

    Args:
        matrices: (..., 3, 3).

    Returns:
        (..., 3, 3) proper rotations.
    """
    U, _, Vh = torch.linalg.svd(matrices)
    det = torch.det(U @ Vh)
    D = torch.ones_like(matrices[..., 0])
    D[..., 2] = det.sign()
    return U @ (D[..., :, None] * Vh)


def rigid_point_frames(
    transforms: torch.Tensor,
    weights: torch.Tensor,
    indices: torch.Tensor,
    rest_points: torch.Tensor,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Per-frame rotation and translation of skinned points relative to the rest pose.

    Each point's blended skinning matrix is projected to its nearest rotation R,
    and the translation t is chosen so that ``R @ rest + t`` is the skinned point
    exactly: this is the ``{R_t, T_t}`` of the paper's body seed points (3.2).

    Args:
        transforms: (T, J, 4, 4) joint skinning transforms.
        weights: (N, K) skinning weights of the points.
        indices: (N, K) joint indices of the points.
        rest_points: (N, 3) the points at the rest pose.

    Returns:
        rotations (T, N, 3, 3) and translations (T, N, 3).
    """
    blended = blend_transforms(transforms, weights, indices)  # (T, N, 4, 4)
    posed = (blended[..., :3, :3] @ rest_points[None, :, :, None])[..., 0] + blended[..., :3, 3]
    rotations = nearest_rotation(blended[..., :3, :3])
    translations = posed - (rotations @ rest_points[None, :, :, None])[..., 0]
    return rotations, translations
