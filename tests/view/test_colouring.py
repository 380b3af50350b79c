"""The viewer's per-vertex values and colour bins, against loops and analytic answers."""

import numpy as np
import pytest
import trimesh

from loosefit.geometry.query import Surface
from loosefit.types import GarmentTemplate
from loosefit.view import colouring


def _square() -> GarmentTemplate:
    """Two triangles on the unit square; a waist of one vertex leaves no edge out."""
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    f = np.array([[0, 1, 2], [0, 2, 3]], np.int64)
    return GarmentTemplate(v, f, v[:, :2].copy(), f.copy(), np.array([0]), name="square")


def test_vertex_error_is_each_vertex_distance():
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(50, 3)), rng.normal(size=(50, 3))
    want = [np.sqrt(sum((a[v, k] - b[v, k]) ** 2 for k in range(3))) for v in range(50)]
    assert np.allclose(colouring.vertex_error(a, b), want)


def test_vertex_strain_is_the_worst_edge_at_each_vertex():
    t = _square()
    g = t.vertices.copy()
    g[2, 0] = 1.5  # the edges (1, 2) 1 -> ~1.118 and (2, 3) 1 -> 1.5 stretch
    s = colouring.vertex_strain(g, t)
    d12 = np.hypot(0.5, 1.0) - 1.0
    d02 = np.hypot(1.5, 1.0) / np.sqrt(2.0) - 1.0  # the diagonal (0, 2)
    assert s[3] == pytest.approx(0.5, abs=1e-6)
    assert s[1] == pytest.approx(d12, abs=1e-6)
    assert s[2] == pytest.approx(0.5, abs=1e-6)
    assert s[0] == pytest.approx(d02, abs=1e-6)


def test_inside_depth_in_a_sphere():
    ball = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    surface = Surface(ball.vertices, ball.faces, winding_number=True)
    points = np.array([[0, 0, 0.5], [0, 0, 0.9], [0, 0, 1.5], [2.0, 0, 0]])
    depth = colouring.inside_depth(surface, points)
    assert depth[0] == pytest.approx(0.5, abs=0.01)
    assert depth[1] == pytest.approx(0.1, abs=0.01)
    assert depth[2] == 0.0 and depth[3] == 0.0


def test_face_bins_and_split_rebuild_the_faces():
    rng = np.random.default_rng(1)
    faces = rng.integers(0, 40, size=(60, 3))
    values = rng.uniform(0, 2.0, size=40)
    bins = colouring.face_bins(faces, values, vmax=1.0, bins=5)
    for f, b in zip(faces, bins, strict=True):  # the loop: the mean in steps of 0.2, clipped
        assert b == min(int(values[f].mean() / 0.2), 4)
    parts = colouring.split_by_bin(faces, bins, 5)
    rebuilt = {k: used[local] for k, (used, local) in enumerate(parts)}
    for k in range(5):
        assert np.array_equal(rebuilt[k], faces[bins == k])
        assert parts[k][1].dtype == np.uint32
    assert sum(len(r) for r in rebuilt.values()) == len(faces)


def test_colour_bar_names_the_scale():
    html = colouring.colour_bar_html(colouring.SCALES["error"], 0.04, 4)
    assert "distance to the reference (cm)" in html
    assert html.count("background:rgb(") == 4
    assert ">4<" in html and ">2<" in html and ">0<" in html
    assert colouring.bin_colours("viridis", 4).shape == (4, 3)
