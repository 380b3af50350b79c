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
    f = np.concatenate([
        np.stack([i[:-1, :-1].ravel(), i[1:, :-1].ravel(), i[:-1, 1:].ravel()], 1),
        np.stack([i[1:, :-1].ravel(), i[1:, 1:].ravel(), i[:-1, 1:].ravel()], 1),
    ])  # fmt: skip
    return v, f
