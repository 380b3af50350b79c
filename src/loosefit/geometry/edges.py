"""A triangle mesh's undirected edges."""

from __future__ import annotations

import numpy as np


def unique_edges(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Undirected edges of a triangle mesh and how many faces use each.

    Args:
        faces: (F, 3) vertex indices.

    Returns:
        edges: (E, 2) int64 vertex pairs with ``edges[:, 0] < edges[:, 1]``, sorted.
        counts: (E,) int64 number of faces using each edge.
    """
    faces = np.asarray(faces, dtype=np.int64)
    half = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)  # (3F, 2) directed edges
    undirected = np.sort(half, axis=1)
    edges, counts = np.unique(undirected, axis=0, return_counts=True)
    return edges.reshape(-1, 2).astype(np.int64), counts.astype(np.int64)
