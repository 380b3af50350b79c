"""The rest lengths a garment fitted with ``garment --fit`` is simulated with, against the
garment file's, and how far the fit's drape stretches it from them, on the parametric
strapless dress made for another body (as tests/fitting/test_drape.py makes it, at full resolution)
and fitted to the default avatar.

The simulator takes the cloth's rest shape from the template's ``rest_vertices`` (the file
as placed) and starts from its ``vertices`` (the drape): the first should not differ from the
file at all, the second is the stretch the simulation starts with.

Usage:
    .venv/bin/python bench/quality/fit_strain.py
    # the garment bench/quality/fit_dress.py fitted:
    .venv/bin/python bench/quality/fit_strain.py --fitted runs/fit_dress/fitted.npz

docs/use/YOUR_GARMENT.md quotes its output.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from loosefit.body.avatar import Avatar, AvatarConfig
from loosefit.fitting.drape import FitConfig, fit_garment
from loosefit.fitting.place import fit_dress, import_garment
from loosefit.garment.dress import DressConfig
from loosefit.garment.obj import write_obj
from loosefit.types import GarmentTemplate

OTHER_BODY = {"weight": 0.8, "height": 0.9, "proportions": 0.0}


def edge_lengths(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(E,) the length of each undirected edge of a mesh (V, 3), (F, 3)."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e = np.unique(np.sort(e, 1), axis=0)
    return np.linalg.norm(vertices[e[:, 0]] - vertices[e[:, 1]], axis=1)


def describe(r: np.ndarray) -> str:
    """A relative change of edge lengths (E,) in one line."""
    return (
        f"median {np.median(r):+.2%}, 5th-95th percentile {np.percentile(r, 5):+.2%} to "
        f"{np.percentile(r, 95):+.2%}, largest {np.abs(r).max():.1%}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--fitted",
        help="a template fitted already (bench/quality/fit_dress.py's "
        "fitted.npz, the same dress): measured, not fitted again",
    )
    args = parser.parse_args()
    dress = fit_dress(
        Avatar(AvatarConfig(shape=OTHER_BODY)), DressConfig.preset("cpu", "strapless")
    )
    v = dress.vertices.astype(np.float64) * 100.0  # centimetres, Y up, as another tool writes
    v = np.stack([v[:, 0], v[:, 2], -v[:, 1]], 1)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "other_dress.obj"
        write_obj(path, v.astype(np.float32), dress.faces, dress.uvs, dress.face_uvs)
        avatar = Avatar()
        placed = import_garment(path, avatar, kind="dress", check=False)[0]
        t0 = time.perf_counter()
        if args.fitted:
            fitted = GarmentTemplate.load(args.fitted)
            how = f"read from {args.fitted}, fitted in {fitted.meta['fit']['seconds']:.0f} s"
        else:
            fit = fit_garment(path, config=FitConfig(), kind="dress", avatar=avatar)
            fitted, report = fit.template, fit.report
            how = f"fitted in {time.perf_counter() - t0:.0f} s; {report.format()}"
    file = edge_lengths(placed.vertices, placed.faces)
    print(f"fit: {fitted.num_vertices} vertices, {how}")
    print(
        "rest lengths the simulator uses against the file's: "
        + describe(edge_lengths(fitted.rest, placed.faces) / file - 1)
    )
    print(
        "the drape (where the simulation starts) against them: "
        + describe(edge_lengths(fitted.vertices, placed.faces) / file - 1)
    )


if __name__ == "__main__":
    main()
