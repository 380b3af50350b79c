"""Matching data to checkpoints: the same garment, rebuilt on another machine."""

from __future__ import annotations

import numpy as np

from loosefit.garment.fingerprint import garment_fingerprint, same_garment
from loosefit.types import GarmentTemplate
from tests.meshes import grid


def _template(vertices: np.ndarray, faces: np.ndarray) -> GarmentTemplate:
    return GarmentTemplate(vertices, faces, vertices[:, :2].copy(), faces, np.arange(3))


def test_a_last_bit_difference_is_the_same_garment_though_the_hash_may_differ():
    v, f = grid(5, 0.0, 0.3)
    # two neighbouring floats on either side of a rounding boundary of the 5 decimals
    x = np.float32(0.12345)
    while np.round(x, 5) == np.round(np.nextafter(x, np.float32(1.0)), 5):
        x = np.nextafter(x, np.float32(1.0))
    v[0, 0] = x
    w = v.copy()
    w[0, 0] = np.nextafter(x, np.float32(1.0))
    a, b = _template(v, f), _template(w, f)
    assert same_garment(a, b)
    # the hash alone would have refused it (what happened to salsa rebuilt on a new machine)
    assert garment_fingerprint(v, f) != garment_fingerprint(w, f)


def test_another_shape_or_other_triangles_is_another_garment():
    v, f = grid(5, 0.0, 0.3)
    moved = v.copy()
    moved[3, 2] += 0.01
    assert not same_garment(_template(v, f), _template(moved, f))
    assert not same_garment(_template(v, f), _template(v, f[:, [0, 2, 1]]))
    assert not same_garment(_template(v, f), _template(*grid(4, 0.0, 0.3)))
