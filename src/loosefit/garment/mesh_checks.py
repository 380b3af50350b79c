"""Pure checks on triangle meshes and their UV layouts (numpy in, numpy out).

Shapes: V vertices, F faces, E edges, U UV coordinates. Nothing here raises on
a bad mesh; callers decide what is an error (see :mod:`loosefit.garment.obj`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from loosefit.geometry.edges import unique_edges


def triangle_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unsigned triangle areas.

    Args:
        vertices: (V, 3) positions.
        faces: (F, 3) vertex indices.

    Returns:
        (F,) float64 areas.
    """
    tri = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]  # (F, 3, 3)
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # (F, 3)
    return 0.5 * np.linalg.norm(cross, axis=1)


def degenerate_faces(vertices: np.ndarray, faces: np.ndarray, rel_eps: float = 1e-12) -> np.ndarray:
    """Indices of zero-area triangles (repeated corners, collinear corners).

    A triangle counts as degenerate when its area is at most ``rel_eps`` times
    the squared diagonal of the mesh's bounding box.

    Args:
        vertices: (V, 3) positions.
        faces: (F, 3) vertex indices.
        rel_eps: area tolerance relative to the squared bounding-box diagonal.

    Returns:
        (K,) int64 face indices, ascending.
    """
    faces = np.asarray(faces, dtype=np.int64)
    if len(faces) == 0:
        return np.zeros(0, dtype=np.int64)
    used = np.asarray(vertices, dtype=np.float64)[np.unique(faces)]
    diag2 = float(np.sum((used.max(0) - used.min(0)) ** 2))
    repeated = (
        (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 2] == faces[:, 0])
    )
    tiny = triangle_areas(vertices, faces) <= rel_eps * max(diag2, np.finfo(np.float64).tiny)
    return np.flatnonzero(repeated | tiny).astype(np.int64)


def nonmanifold_edges(faces: np.ndarray) -> np.ndarray:
    """Edges shared by more than two faces.

    Args:
        faces: (F, 3) vertex indices.

    Returns:
        (E, 2) int64 vertex pairs (smaller index first), sorted.
    """
    edges, counts = unique_edges(faces)
    return edges[counts > 2]


def boundary_loops(faces: np.ndarray) -> list[np.ndarray]:
    """Closed chains of boundary edges (edges used by exactly one face).

    Each loop follows the faces' winding, so for a mesh wound counter-clockwise
    seen from outside, a loop runs with the surface on its left. Loops are
    ordered by their smallest vertex index. Where boundaries touch at a vertex
    (a non-manifold vertex) a chain may end before closing; it is returned as is.

    Args:
        faces: (F, 3) vertex indices.

    Returns:
        A list of (n_k,) int64 vertex index arrays, one per loop, without
        repeating the first vertex at the end.
    """
    faces = np.asarray(faces, dtype=np.int64)
    if len(faces) == 0:
        return []
    half = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)  # (3F, 2)
    _, inverse, counts = np.unique(
        np.sort(half, axis=1), axis=0, return_inverse=True, return_counts=True
    )
    boundary = half[counts[inverse.reshape(-1)] == 1]  # (B, 2) directed boundary edges
    following: dict[int, list[int]] = {}
    for a, b in boundary.tolist():
        following.setdefault(a, []).append(b)
    loops: list[np.ndarray] = []
    for start in sorted(following):
        while following.get(start):
            loop = [start]
            current = following[start].pop()
            while current != start and following.get(current):
                loop.append(current)
                current = following[current].pop()
            if current != start:
                loop.append(current)  # an open chain at a non-manifold vertex
            loops.append(np.asarray(loop, dtype=np.int64))
    return loops


def hem_loop(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(H,) int64: a garment's lower opening, the boundary loop lowest on average (+Z up);
    empty for a closed mesh."""
    loops = boundary_loops(faces)
    if not loops:
        return np.zeros(0, np.int64)
    z = np.asarray(vertices)[:, 2]
    return min(loops, key=lambda loop: float(z[loop].mean()))


def uv_triangle_areas(uvs: np.ndarray, face_uvs: np.ndarray) -> np.ndarray:
    """Signed areas of the faces in UV space (positive = counter-clockwise).

    Args:
        uvs: (U, 2) UV coordinates.
        face_uvs: (F, 3) indices into ``uvs``.

    Returns:
        (F,) float64 signed areas.
    """
    tri = np.asarray(uvs, dtype=np.float64)[np.asarray(face_uvs)]  # (F, 3, 2)
    e1 = tri[:, 1] - tri[:, 0]
    e2 = tri[:, 2] - tri[:, 0]
    return 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])


def uv_charts(face_uvs: np.ndarray, num_uvs: int) -> np.ndarray:
    """Connected pieces (charts) of a UV layout.

    Args:
        face_uvs: (F, 3) indices into a (U, 2) UV array.
        num_uvs: U.

    Returns:
        (U,) int64 chart label of every UV coordinate (unreferenced ones get their own).
    """
    face_uvs = np.asarray(face_uvs, dtype=np.int64)
    rows = face_uvs[:, [0, 1, 2]].reshape(-1)
    cols = face_uvs[:, [1, 2, 0]].reshape(-1)
    graph = sp.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(num_uvs, num_uvs))
    _, labels = connected_components(graph, directed=False)
    return labels.astype(np.int64)
