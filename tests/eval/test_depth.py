"""The depth inside the body frame by frame (loosefit.eval.depth), on a moving box whose
distances are known in closed form."""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.eval.depth import body_hits, body_surfaces, inside_depths
from tests.meshes import cube

HALF = 0.2  # m, half the box's side


def moving_box(frames: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A 0.4 m box sliding 3 cm a frame along x: body (T, 8, 3), faces (12, 3), centres
    (T, 3)."""
    v, f = cube(2 * HALF)
    centres = np.zeros((frames, 3), np.float32)
    centres[:, 0] = 0.03 * np.arange(frames)
    return v[None] + centres[:, None], f, centres


def box_reference(points: np.ndarray, centre: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inside and the distance to the box's surface of each point (N, 3), point by point."""
    inside, distance = np.zeros(len(points), bool), np.zeros(len(points))
    for i, p in enumerate(points.astype(np.float64) - centre):
        gap = np.abs(p) - HALF  # (3,) per axis, < 0 inside the slab
        if (gap < 0).all():
            inside[i], distance[i] = True, -gap.max()
        else:
            distance[i] = np.linalg.norm(np.maximum(gap, 0.0))
    return inside, distance


@pytest.fixture(scope="module")
def case():
    T, V = 5, 40
    body, faces, centres = moving_box(T)
    rng = np.random.default_rng(3)
    garment = (centres[:, None] + rng.uniform(-0.3, 0.3, (T, V, 3))).astype(np.float32)
    return garment, body, faces, centres


def test_body_hits_follow_the_body_frame_by_frame(case):
    garment, body, faces, centres = case
    hits = list(body_hits(garment, body, faces))
    assert len(hits) == len(garment)
    for t, hit in enumerate(hits):
        inside, distance = box_reference(garment[t], centres[t])
        np.testing.assert_array_equal(hit.inside, inside)
        np.testing.assert_allclose(hit.distance, distance, atol=1e-5)


def test_inside_depths_against_a_plain_loop(case):
    garment, body, faces, centres = case
    share, deepest = inside_depths(garment, body, faces)
    for t in range(len(garment)):
        inside, distance = box_reference(garment[t], centres[t])
        assert share[t] == inside.mean()
        expect = distance[inside].max() if inside.any() else 0.0
        assert deepest[t] == pytest.approx(expect, abs=1e-5)
    assert share.max() > 0  # the case has vertices inside to measure


def test_a_frame_with_none_inside_has_no_depth():
    body, faces, centres = moving_box(2)
    garment = (centres[:, None] + np.array([[0.5, 0.0, 0.0], [0.0, -0.4, 0.1]])).astype(np.float32)
    share, deepest = inside_depths(garment, body, faces)
    np.testing.assert_array_equal(share, [0.0, 0.0])
    np.testing.assert_array_equal(deepest, [0.0, 0.0])


def test_vertices_beyond_the_reach_are_outside():
    body, faces, centres = moving_box(1)
    garment = (centres[:, None] + np.array([[0.0, 0.0, 0.1], [0.0, 0.0, 0.9]])).astype(np.float32)
    (hit,) = body_hits(garment, body, faces, max_distance=0.5)
    np.testing.assert_array_equal(hit.faces >= 0, [True, False])
    share, deepest = inside_depths(garment, body, faces, max_distance=0.5)
    assert share[0] == 0.5 and deepest[0] == pytest.approx(0.1, abs=1e-6)


def test_the_surface_follows_the_body(case):
    garment, body, faces, centres = case
    seen = 0
    for t, surface in enumerate(body_surfaces(body, faces)):
        inside, distance = box_reference(garment[t], centres[t])
        hit = surface.query(garment[t])
        np.testing.assert_array_equal(hit.inside, inside)
        np.testing.assert_allclose(hit.distance, distance, atol=1e-5)
        seen += 1
    assert seen == len(body)
    assert list(body_surfaces(body[:0], faces)) == []
