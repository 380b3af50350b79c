"""Mesh geometry for rendering: smooth vertex normals and a few primitive meshes.

The primitives (sphere, capsule, open cone) stand in for a body and a skirt in
tests, benchmarks and quick looks; they follow loosefit's conventions (metres,
Z up, counter-clockwise faces seen from outside).
"""

from __future__ import annotations

import numpy as np

from loosefit.errors import LoosefitInputError


def _check_faces(faces: np.ndarray, num_vertices: int, source: str) -> np.ndarray:
    """Return ``faces`` as an (F, 3) int64 array, or raise if it is malformed."""
    faces = np.asarray(faces)
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise LoosefitInputError(source, "faces", "shape (F, 3)", f"shape {faces.shape}")
    if not np.issubdtype(faces.dtype, np.integer):
        raise LoosefitInputError(source, "faces", "an integer array", f"dtype {faces.dtype}")
    if faces.size and (faces.min() < 0 or faces.max() >= num_vertices):
        raise LoosefitInputError(
            source,
            "faces",
            f"indices in [0, {num_vertices})",
            f"range [{faces.min()}, {faces.max()}]",
        )
    return faces.astype(np.int64, copy=False)


class NormalPlan:
    """The scatter pattern of a face list, reused to compute normals of many frames.

    Face normals are summed onto the three corners of each face by sorting the
    corners once (``argsort``) and reducing contiguous runs (``np.add.reduceat``),
    which works for any number of leading batch dimensions.

    Attributes:
        faces: (F, 3) int64 triangle indices.
        num_vertices: V, the number of vertices the faces index into.
    """

    def __init__(self, faces: np.ndarray, num_vertices: int) -> None:
        self.faces = _check_faces(faces, num_vertices, "smooth_vertex_normals")
        self.num_vertices = int(num_vertices)
        corners = self.faces.reshape(-1)  # (3F,) vertex of each face corner
        self._order = np.argsort(corners, kind="stable")  # (3F,)
        ordered = corners[self._order]
        is_start = np.ones(len(ordered), dtype=bool)
        is_start[1:] = ordered[1:] != ordered[:-1]
        self._starts = np.flatnonzero(is_start)  # (U,) first corner of each used vertex
        self._used = ordered[self._starts]  # (U,) vertices that belong to a face
        # Face of each sorted corner: corner k belongs to face k // 3.
        self._corner_face = self._order // 3  # (3F,)

    def __call__(self, vertices: np.ndarray) -> np.ndarray:
        """Unit area-weighted vertex normals, see :func:`smooth_vertex_normals`."""
        v = np.asarray(vertices)
        if v.ndim < 2 or v.shape[-2:] != (self.num_vertices, 3):
            raise LoosefitInputError(
                "smooth_vertex_normals",
                "vertices",
                f"shape (..., {self.num_vertices}, 3)",
                f"shape {v.shape}",
            )
        dtype = np.result_type(v.dtype, np.float32)
        v = v.astype(dtype, copy=False)
        out = np.zeros(v.shape, dtype=dtype)  # (..., V, 3)
        if len(self._used) == 0:
            return out
        f = self.faces
        v0, v1, v2 = v[..., f[:, 0], :], v[..., f[:, 1], :], v[..., f[:, 2], :]  # (..., F, 3)
        face_n = np.cross(v1 - v0, v2 - v0)  # (..., F, 3), length = 2 * area
        per_corner = face_n[..., self._corner_face, :]  # (..., 3F, 3) in sorted corner order
        out[..., self._used, :] = np.add.reduceat(per_corner, self._starts, axis=-2)  # (..., U, 3)
        length = np.linalg.norm(out, axis=-1, keepdims=True)  # (..., V, 1)
        np.divide(out, length, out=out, where=length > 1e-20)
        return out


def smooth_vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit vertex normals: the area-weighted sum of the normals of the faces around each vertex.

    Face normals follow the right-hand rule (counter-clockwise corners point
    the normal at the viewer). A vertex in no face, or whose faces cancel out,
    gets a zero normal.

    Args:
        vertices: (..., V, 3) float positions; leading dimensions (e.g. T frames) are batched.
        faces: (F, 3) int triangle vertex indices.

    Returns:
        (..., V, 3) float normals (float64 for integer input, float32 for float16, else the
        input dtype).

    Raises:
        LoosefitInputError: if the shapes do not match or a face index is out of range.
    """
    v = np.asarray(vertices)
    if v.ndim < 2 or v.shape[-1] != 3:
        raise LoosefitInputError(
            "smooth_vertex_normals", "vertices", "shape (..., V, 3)", f"shape {v.shape}"
        )
    return NormalPlan(faces, v.shape[-2])(v)


def surface_of_revolution(profile: np.ndarray, segments: int) -> tuple[np.ndarray, np.ndarray]:
    """Revolve a profile curve about the Z axis.

    The profile runs upwards; a point with radius 0 at either end becomes a
    single pole vertex closing that end, otherwise the end is left open (as a
    skirt's hem and waist are). Faces are counter-clockwise seen from outside.

    Args:
        profile: (K, 2) float ``(radius, z)`` points, bottom to top.
        segments: number of vertices around each ring (>= 3).

    Returns:
        vertices (V, 3) float32 and faces (F, 3) int64.
    """
    profile = np.asarray(profile, dtype=np.float64)
    if profile.ndim != 2 or profile.shape[1] != 2 or len(profile) < 2:
        raise LoosefitInputError(
            "surface_of_revolution", "profile", "shape (K>=2, 2)", str(profile.shape)
        )
    if segments < 3:
        raise LoosefitInputError("surface_of_revolution", "segments", ">= 3", str(segments))
    bottom_pole = profile[0, 0] == 0.0
    top_pole = profile[-1, 0] == 0.0
    rings = profile[int(bottom_pole) : len(profile) - int(top_pole)]  # (R, 2)
    R, S = len(rings), segments
    theta = np.linspace(0.0, 2.0 * np.pi, S, endpoint=False)  # (S,) counter-clockwise from above
    ring_xyz = np.stack(
        [
            rings[:, None, 0] * np.cos(theta)[None],
            rings[:, None, 0] * np.sin(theta)[None],
            np.repeat(rings[:, None, 1], S, axis=1),
        ],
        axis=-1,
    ).reshape(R * S, 3)  # (R*S, 3)
    verts = [ring_xyz]
    faces = []
    ring = np.arange(R * S).reshape(R, S)  # (R, S) vertex index of ring r, segment s
    a, b = ring[:-1], np.roll(ring[:-1], -1, axis=1)  # lower ring: s, s+1
    c, d = np.roll(ring[1:], -1, axis=1), ring[1:]  # upper ring: s+1, s
    faces.append(np.stack([a, b, c], axis=-1).reshape(-1, 3))
    faces.append(np.stack([a, c, d], axis=-1).reshape(-1, 3))
    n = R * S
    if bottom_pole:
        verts.append([[0.0, 0.0, profile[0, 1]]])
        first = ring[0]
        faces.append(np.stack([np.full(S, n), np.roll(first, -1), first], axis=-1))
        n += 1
    if top_pole:
        verts.append([[0.0, 0.0, profile[-1, 1]]])
        last = ring[-1]
        faces.append(np.stack([np.full(S, n), last, np.roll(last, -1)], axis=-1))
        n += 1
    return np.concatenate(verts).astype(np.float32), np.concatenate(faces).astype(np.int64)


def uv_sphere(
    radius: float = 1.0, segments: int = 32, rings: int = 16, center=(0.0, 0.0, 0.0)
) -> tuple[np.ndarray, np.ndarray]:
    """A closed UV sphere.

    Returns:
        vertices (V, 3) float32 with V = segments * (rings - 1) + 2, faces (F, 3) int64.
    """
    phi = np.linspace(np.pi, 0.0, rings + 1)  # polar angle, bottom pole to top pole
    profile = np.stack([radius * np.sin(phi), radius * np.cos(phi)], axis=-1)
    profile[[0, -1], 0] = 0.0
    v, f = surface_of_revolution(profile, segments)
    return v + np.asarray(center, dtype=np.float32), f


def capsule(
    radius: float = 0.15, height: float = 1.7, segments: int = 64, rings: int = 64
) -> tuple[np.ndarray, np.ndarray]:
    """A closed capsule along Z standing on z = 0 (a stand-in for a body).

    Args:
        radius: cap and cylinder radius, metres.
        height: total height including both caps, metres (>= 2 * radius).
        segments: vertices around each ring.
        rings: profile points, split between the two caps and the cylinder.

    Returns:
        vertices (V, 3) float32 and faces (F, 3) int64.
    """
    cap = max(rings // 4, 2)
    phi = np.linspace(0.0, np.pi / 2, cap + 1)  # 0 at the pole
    bottom = np.stack([radius * np.sin(phi), radius * (1 - np.cos(phi))], axis=-1)  # (cap+1, 2)
    top = bottom[::-1] * [1.0, -1.0] + [0.0, height]
    middle_z = np.linspace(radius, height - radius, max(rings - 2 * cap, 2))[1:-1]
    middle = np.stack([np.full_like(middle_z, radius), middle_z], axis=-1)
    profile = np.concatenate([bottom, middle, top])
    profile[[0, -1], 0] = 0.0
    return surface_of_revolution(profile, segments)


def open_cone(
    waist_radius: float = 0.17,
    hem_radius: float = 0.45,
    waist_z: float = 1.0,
    hem_z: float = 0.45,
    segments: int = 64,
    rings: int = 32,
) -> tuple[np.ndarray, np.ndarray]:
    """An open conical surface, open at both ends (a stand-in for a skirt).

    Returns:
        vertices (V, 3) float32 with V = segments * rings, faces (F, 3) int64.
    """
    s = np.linspace(0.0, 1.0, rings)
    profile = np.stack(
        [hem_radius + s * (waist_radius - hem_radius), hem_z + s * (waist_z - hem_z)], -1
    )
    return surface_of_revolution(profile, segments)
