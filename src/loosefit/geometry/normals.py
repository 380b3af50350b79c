"""Surface normals of triangle meshes, batched over frames."""

from __future__ import annotations

import torch


def face_normals(vertices: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
    """Area-weighted (unnormalised) face normals.

    Args:
        vertices: (..., V, 3).
        faces: (F, 3) vertex indices, counter-clockwise seen from the normal's side.

    Returns:
        (..., F, 3), each of length twice the triangle's area.
    """
    a, b, c = (vertices[..., faces[:, i], :] for i in range(3))
    return torch.linalg.cross(b - a, c - a)


def vertex_normals(vertices: torch.Tensor, faces: torch.Tensor, eps: float = 1e-12) -> torch.Tensor:
    """Unit vertex normals: the area-weighted mean of the incident face normals.

    Args:
        vertices: (..., V, 3).
        faces: (F, 3).

    Returns:
        (..., V, 3) unit normals (zero for unreferenced vertices).
    """
    fn = face_normals(vertices, faces)  # (..., F, 3)
    out = torch.zeros_like(vertices)
    for i in range(3):
        out.index_add_(-2, faces[:, i], fn)
    return out / out.norm(dim=-1, keepdim=True).clamp_min(eps)
