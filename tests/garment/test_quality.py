"""The plausibility figures of a garment sequence on its body."""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.garment.quality import quality
from loosefit.geometry.edges import unique_edges
from loosefit.types import GarmentTemplate
from tests.meshes import cube


def test_quality_on_known_cases():
    body, body_faces = cube(0.2)
    v, f = cube(1.0)  # a "garment": a unit cube around a small body cube
    garment = GarmentTemplate(v, f, np.zeros((1, 2)), np.zeros_like(f), np.zeros(0, np.int64))
    g = np.stack([v, v + [0.0, 0.0, 0.1]]).astype(np.float32)  # (2, 8, 3): lifted by 10 cm
    b = np.stack([body, body + [0.0, 0.0, 0.1]])
    q = quality(g, garment, b, body_faces, fps=30.0)
    assert q["inside_max"] == 0.0 and q["inside_depth_max"] == 0.0 and q["nan_count"] == 0
    assert q["strain_max"] < 1e-6
    assert q["max_speed"] == pytest.approx(3.0, rel=1e-5)  # 0.1 m in 1/30 s
    g[1, 0] = [0.0, 0.0, 0.1]  # one vertex at the body's centre
    g[0, 1] = np.nan
    q = quality(g, garment, b, body_faces, fps=30.0)
    np.testing.assert_allclose(q["inside_fraction"], [0.0, 1.0 / 8.0])
    np.testing.assert_allclose(q["penetration_fraction"], [0.0, 1.0 / 8.0])  # 10 cm deep
    assert q["nan_count"] == 1 and q["inside_depth_max"] == pytest.approx(0.1, abs=1e-5)
    g[1, 0] = [0.0, 0.0, 0.2 - 0.004]  # 4 mm inside the top: touching, not penetrating
    q = quality(g, garment, b, body_faces, fps=30.0)
    np.testing.assert_allclose(q["inside_fraction"], [0.0, 1.0 / 8.0])
    assert q["penetration_max"] == 0.0
    assert q["inside_depth_max"] == pytest.approx(0.004, abs=1e-5)
    edges, _ = unique_edges(f)
    assert len(edges) == 18  # a cube's 12 sides and 6 face diagonals
    with pytest.raises(LoosefitInputError):
        quality(g[:, :5], garment, b, body_faces)


def test_strain_is_measured_against_the_rest_shape_not_the_start():
    """A template that starts stretched (a fitted garment, draped): its rest lengths are
    its ``rest_vertices``'."""
    from loosefit.garment.quality import edge_strain

    v, f = cube(1.0)
    start = (1.1 * v).astype(np.float32)
    garment = GarmentTemplate(
        start, f, np.zeros((1, 2)), np.zeros_like(f), np.zeros(0, np.int64), rest_vertices=v
    )
    strain, _ = edge_strain(start[None], garment)
    np.testing.assert_allclose(strain, 0.1, atol=1e-5)
    plain = GarmentTemplate(start, f, np.zeros((1, 2)), np.zeros_like(f), np.zeros(0, np.int64))
    assert edge_strain(start[None], plain)[0].max() < 1e-6
