"""How much ``garment --fit``'s drape changes a garment's edge lengths (its rest lengths after the
fit), on the parametric strapless dress made for another body (as tests/test_fit.py makes it,
at full resolution) and fitted to the default avatar.

Usage:
    .venv/bin/python bench/fit_strain.py

docs/YOUR_GARMENT.md quotes its output.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from loosefit.body.avatar import Avatar, AvatarConfig
from loosefit.dress import fit_dress, import_garment
from loosefit.fit import FitConfig, fit_garment
from loosefit.garment.dress import DressConfig
from loosefit.garment.obj import write_obj

OTHER_BODY = {"weight": 0.8, "height": 0.9, "proportions": 0.0}


def edge_lengths(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(E,) the length of each undirected edge of a mesh (V, 3), (F, 3)."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e = np.unique(np.sort(e, 1), axis=0)
    return np.linalg.norm(vertices[e[:, 0]] - vertices[e[:, 1]], axis=1)


def main() -> None:
    dress = fit_dress(Avatar(AvatarConfig(shape=OTHER_BODY)),
                      DressConfig.preset("cpu", "strapless"))  # fmt: skip
    v = dress.vertices.astype(np.float64) * 100.0  # centimetres, Y up, as another tool writes
    v = np.stack([v[:, 0], v[:, 2], -v[:, 1]], 1)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "other_dress.obj"
        write_obj(path, v.astype(np.float32), dress.faces, dress.uvs, dress.face_uvs)
        avatar = Avatar()
        placed = import_garment(path, avatar, kind="dress", check=False)[0]
        t0 = time.perf_counter()
        fitted, report, _ = fit_garment(path, config=FitConfig(), kind="dress", avatar=avatar)
        seconds = time.perf_counter() - t0
    r = edge_lengths(fitted.vertices, placed.faces) / edge_lengths(placed.vertices, placed.faces)
    r -= 1
    print(f"fit: {seconds:.0f} s, {fitted.num_vertices} vertices; {report.format()}")
    print(f"edge length change: median {np.median(r):+.2%}, 5th-95th percentile "
          f"{np.percentile(r, 5):+.2%} to {np.percentile(r, 95):+.2%}, largest "
          f"{np.abs(r).max():.1%}")  # fmt: skip


if __name__ == "__main__":
    main()
