"""The waistband's glue (loosefit.sim.waist) on a synthetic body."""

from __future__ import annotations

import math

import numpy as np

from loosefit.geometry.query import closest_points
from loosefit.sim.waist import glue_waist, glued_points
from tests.meshes import cube


def test_glue_holds_points_on_a_moving_body():
    v, f = cube(0.4)
    ring = np.array([[0.25 * math.cos(a), 0.25 * math.sin(a), 0.05] for a in np.linspace(0, 6, 12)])
    exact = glue_waist(ring, v, f, None)
    np.testing.assert_allclose(glued_points(exact, v, f), ring, atol=1e-5)
    snug = glue_waist(ring, v, f, 0.01)
    hit = closest_points(v, f, glued_points(snug, v, f))
    np.testing.assert_allclose(hit.distance, 0.01, atol=1e-5)
    assert not hit.inside.any()
    # A rigid motion of the body carries the glued points with it.
    c, s = math.cos(0.7), math.sin(0.7)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    moved = v @ rot.T + [1.0, 2.0, 3.0]
    np.testing.assert_allclose(
        glued_points(exact, moved, f), ring @ rot.T + [1.0, 2.0, 3.0], atol=1e-5
    )
