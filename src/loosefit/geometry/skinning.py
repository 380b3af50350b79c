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


def linear_blend_skinning(
    points: torch.Tensor, weights: torch.Tensor, transforms: torch.Tensor
) -> torch.Tensor:
    """Linear blend skinning ``x_i = sum_k w_ik A_k [p_i; 1]``, batched.

    Args:
        points: (..., V, 3) points in the rest space (a (V, 3) rest shape broadcasts).
        weights: (V, K) skinning weights, rows summing to 1 (dense).
        transforms: (..., K, 3, 4) rest -> posed affine transforms of the K influences.

    Returns:
        (..., V, 3) posed points; differentiable w.r.t. all three.
    """
    blended = torch.einsum("vk,...kij->...vij", weights, transforms)  # (..., V, 3, 4)
    return (blended[..., :3] @ points[..., None])[..., 0] + blended[..., 3]


def dense_weights(weights: torch.Tensor, indices: torch.Tensor, count: int) -> torch.Tensor:
    """Sparse skinning weights (N, K) on joint ``indices`` (N, K) as a dense (N, count) matrix."""
    out = torch.zeros(weights.shape[0], count, dtype=weights.dtype, device=weights.device)
    return out.scatter_add_(1, indices.long(), weights)


def root_frame_transforms(
    joint_transforms: torch.Tensor, heading: torch.Tensor, origin: torch.Tensor
) -> torch.Tensor:
    """World skinning transforms expressed in the root frame of each frame.

    With ``x_root = H^T (x_world - p)`` (:mod:`loosefit.model.motion_features`), a joint's
    transform rest -> root frame is ``[H^T | -H^T p] T``.

    Args:
        joint_transforms: (T, J, 4, 4) rest -> world skinning transforms.
        heading: (T, 3, 3) H and ``origin`` (T, 3) p of the root frames.

    Returns:
        (T, J, 3, 4) rest -> root-frame transforms.
    """
    Ht = heading.transpose(-1, -2).to(joint_transforms)  # (T, 3, 3)
    rot = Ht[:, None] @ joint_transforms[..., :3, :]  # (T, J, 3, 4)
    shift = (Ht @ origin.to(joint_transforms)[..., None])[..., 0]  # (T, 3)
    rot[..., 3] = rot[..., 3] - shift[:, None]
    return rot
