import numpy as np
import pytest

from loosefit.geometry.query import Surface, closest_points
from tests.meshes import cube

HALF = 0.5  # the unit cube of tests.meshes spans [-0.5, 0.5]^3


def _box_answer(p):
    """The closest points (N, 3), distances (N,) and inside flags (N,) of points p (N, 3)
    to the surface of the box [-HALF, HALF]^3, by plain geometry."""
    inside = (np.abs(p) < HALF).all(1)
    closest = np.clip(p, -HALF, HALF)
    for i in np.flatnonzero(inside):  # inside: straight out through the nearest side
        axis = np.argmax(np.abs(p[i]))
        closest[i, axis] = np.sign(p[i, axis]) * HALF
    return closest, np.linalg.norm(p - closest, axis=1), inside


@pytest.fixture(scope="module")
def points():
    rng = np.random.default_rng(0)
    p = rng.uniform(-1.2, 1.2, (400, 3))
    margin = np.abs(np.abs(p) - HALF).min(1)
    return p[margin > 0.02].astype(np.float32)  # away from the sides (ties of the sign)


@pytest.mark.parametrize("sign", ["winding", "normal", "rays"])
def test_closest_points_match_the_box_by_plain_geometry(points, sign):
    v, f = cube()
    hit = Surface(v, f).query(points, 10.0, sign=sign)
    closest, distance, inside = _box_answer(points.astype(np.float64))
    np.testing.assert_allclose(hit.distance, distance, atol=1e-5)
    np.testing.assert_array_equal(hit.inside, inside)
    # the point lies on its face: the face's corners blended by the barycentric weights
    recon = (hit.barycentric[:, :, None] * v[f[hit.faces]]).sum(1)
    np.testing.assert_allclose(recon, hit.points, atol=1e-5)
    np.testing.assert_allclose(hit.barycentric.sum(1), 1.0, atol=1e-6)
    # where the closest point is unique (not on an edge), it is the box's
    unique = (np.abs(np.abs(closest) - HALF) < 1e-9).sum(1) == 1
    np.testing.assert_allclose(hit.points[unique], closest[unique], atol=1e-5)


def test_a_refitted_surface_answers_for_its_new_place():
    v, f = cube()
    surface = Surface(v, f)
    q = np.array([[0.0, 0.0, 1.5], [2.0, 0.0, 0.1]], np.float32)
    surface.refit(v + np.float32([2.0, 0.0, 0.0]))  # moved 2 m along x
    hit = surface.query(q, 10.0)
    moved = closest_points(v + np.float32([2.0, 0.0, 0.0]), f, q, 10.0)
    np.testing.assert_allclose(hit.points, moved.points, atol=1e-6)
    assert hit.inside.tolist() == [False, True]
    np.testing.assert_allclose(hit.distance, [np.hypot(1.5, 1.0), 0.4], atol=1e-5)


def test_a_hint_gives_the_same_answers(points):
    v, f = cube()
    surface = Surface(v, f)
    first = surface.query(points, 10.0)
    hinted = surface.query(points, 10.0, hint=first.faces)
    np.testing.assert_allclose(hinted.distance, first.distance, atol=1e-6)
    np.testing.assert_array_equal(hinted.inside, first.inside)


def test_inside_by_rays_is_the_rays_query_inside_test(points):
    v, f = cube()
    surface = Surface(v, f)
    hit = surface.query(points, 10.0, sign="rays")
    np.testing.assert_array_equal(surface.inside_by_rays(points, hit.points, hit.faces), hit.inside)
    assert surface.inside_by_rays(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)).shape == (0,)


def test_first_hits_of_rays_through_the_cube():
    v, f = cube()
    surface = Surface(v, f)
    origins = np.array([[0.0, 0.0, -2.0], [0.0, 0.0, 0.0], [3.0, 3.0, 3.0]], np.float32)
    directions = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]], np.float32)
    t, faces = surface.first_hits(origins, directions, 5.0)
    np.testing.assert_allclose(t, [1.5, 0.5, 5.0], atol=1e-6)
    assert faces[2] == -1 and (faces[:2] >= 0).all()
    hit_points = origins[:2] + t[:2, None] * directions[:2]
    for p, face in zip(hit_points, faces[:2], strict=True):  # the face met holds the point
        a, b, c = v[f[face]].astype(np.float64)
        assert abs(np.dot(np.cross(b - a, c - a), p - a)) < 1e-6


def test_the_surface_refuses_wrong_shapes_and_signs():
    v, f = cube()
    surface = Surface(v, f)
    with pytest.raises(ValueError, match=r"vertices: expected \(8, 3\), found \(7, 3\)"):
        surface.refit(v[:7])
    with pytest.raises(ValueError, match="sign: expected 'winding', 'normal' or 'rays'"):
        surface.query(v, sign="inside")
    with pytest.raises(ValueError, match=r"hint: expected \(8,\) faces, found \(3,\)"):
        surface.query(v, hint=np.zeros(3, np.int64))
    with pytest.raises(ValueError, match=r"closest, faces: expected \(8, 3\) and \(8,\)"):
        surface.inside_by_rays(v, v[:2], np.zeros(8))
    with pytest.raises(ValueError, match=r"directions: expected \(8, 3\), found \(2, 3\)"):
        surface.first_hits(v, v[:2], 1.0)
