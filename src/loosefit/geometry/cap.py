"""Cutting a region out of a closed triangle mesh and closing the holes it leaves."""

from __future__ import annotations

import numpy as np

from loosefit.errors import LoosefitInputError


def triangle_keys(*faces: np.ndarray) -> list[np.ndarray]:
    """One int64 per triangle of each (F_i, 3) array, equal for the same three vertices in any
    order (fewer than 2M vertices): [(F_i,) int64], to match triangles across meshes."""
    rows = [np.sort(np.asarray(f, np.int64), axis=1) for f in faces]
    n = max(int(r.max(initial=0)) for r in rows) + 1
    key = np.array([1, n, n * n], np.int64)
    return [r @ key for r in rows]


def boundary_loops(faces: np.ndarray) -> list[np.ndarray]:
    """The holes of a triangle mesh, each as a loop of vertex indices.

    Args:
        faces: (F, 3) consistently oriented triangles.

    Returns:
        One (L,) int64 array per hole, its vertices in the order of the faces'
        own directed edges along the hole (so a cap must run the other way).

    Raises:
        LoosefitInputError: an edge used by more than two faces, or a boundary that
            touches itself at a vertex (a pinch), which has no simple loop.
    """
    faces = np.asarray(faces, np.int64)
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    undirected, counts = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
    if (counts > 2).any():
        bad = undirected[counts > 2][0].tolist()
        raise LoosefitInputError("mesh", "faces", "a manifold mesh", f"edge {bad} in >2 faces")
    single = {tuple(e) for e in undirected[counts == 1].tolist()}
    following: dict[int, int] = {}
    for a, b in directed.tolist():
        if (min(a, b), max(a, b)) in single:
            if a in following:
                raise LoosefitInputError(
                    "mesh", "faces", "holes with simple boundaries", f"a pinch at vertex {a}"
                )
            following[a] = b
    loops = []
    while following:
        start, loop = next(iter(following)), []
        v = start
        while True:
            loop.append(v)
            v = following.pop(v)
            if v == start:
                break
        loops.append(np.asarray(loop, np.int64))
    return loops


def cut_and_cap(faces: np.ndarray, removed: np.ndarray) -> np.ndarray:
    """Take the faces of a vertex region out of a closed mesh and close every hole with a fan.

    A face goes when all three of its vertices are in ``removed``. Each hole is
    closed by a fan from its first vertex, oriented like the rest, so the result
    is closed again (an inside/outside test still works on it) and uses only
    the mesh's own vertices: it can be posed with them.

    Args:
        faces: (F, 3) triangles of a closed, consistently oriented mesh.
        removed: (V,) bool, the vertices of the region to cut away.

    Returns:
        (F', 3) int64 faces: those kept, then the caps.
    """
    faces = np.asarray(faces, np.int64)
    removed = np.asarray(removed, bool)
    kept = faces[~removed[faces].all(axis=1)]
    caps = []
    for loop in boundary_loops(kept):
        # The loop runs along the kept faces' edges; a cap face runs the other way.
        for i in range(1, len(loop) - 1):
            caps.append((loop[0], loop[i + 1], loop[i]))
    return np.concatenate([kept, np.asarray(caps, np.int64).reshape(-1, 3)])
