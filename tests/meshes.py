"""Small meshes the tests share."""

from __future__ import annotations

import numpy as np


def grid(n: int, lo: float, hi: float, z: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """An n x n vertex grid over [lo, hi]^2 at height z: (n^2, 3) float32 and its
    2 (n-1)^2 triangles (F, 3)."""
    u = np.linspace(lo, hi, n)
    X, Y = np.meshgrid(u, u)
    v = np.stack([X.ravel(), Y.ravel(), np.full(n * n, z)], 1).astype(np.float32)
    i = np.arange(n * n).reshape(n, n)
    f = np.concatenate(
        [
            np.stack([i[:-1, :-1].ravel(), i[1:, :-1].ravel(), i[:-1, 1:].ravel()], 1),
            np.stack([i[1:, :-1].ravel(), i[1:, 1:].ravel(), i[:-1, 1:].ravel()], 1),
        ]
    )
    return v, f


def cube(size: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """A closed cube centred at the origin, faces counter-clockwise seen from outside."""
    v = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], np.float32)
    f = np.array(
        [
            [0, 1, 3],
            [0, 3, 2],
            [4, 6, 7],
            [4, 7, 5],
            [0, 4, 5],
            [0, 5, 1],
            [2, 3, 7],
            [2, 7, 6],
            [0, 2, 6],
            [0, 6, 4],
            [1, 5, 7],
            [1, 7, 3],
        ]
    )
    return 0.5 * size * v, f
