import numpy as np

from loosefit.geometry.query import Surface
from loosefit.geometry.signed_distance import (
    beyond_skin,
    face_normals,
    hit_distances,
    on_skin,
    signed_distances,
)
from tests.meshes import cube

# the unit cube of tests.meshes spans [-0.5, 0.5]^3; points over its top face's middle
INSIDE = [0.1, -0.1, 0.3]  # 0.2 below the top
OUTSIDE = [0.0, 0.2, 0.9]  # 0.4 above it
CORNER = [1.0, 1.0, 1.0]  # beyond the corner (0.5, 0.5, 0.5)
ON = [0.2, 0.1, 0.5]  # on the top face
FAR = [9.0, 0.0, 0.0]


def _body():
    v, f = cube()
    return Surface(v, f)


def test_signed_distances_of_points_about_a_box():
    body = _body()
    x = np.array([INSIDE, OUTSIDE, CORNER, ON, FAR])
    n, ds = signed_distances(x, body, reach=2.0)
    np.testing.assert_allclose(ds[:4], [-0.2, 0.4, np.sqrt(3 * 0.25), 0.0], atol=1e-5)
    assert ds[4] == np.inf and (n[4] == 0).all()
    # the distance's gradient: out through the top, and from the corner straight away
    np.testing.assert_allclose(n[[0, 1, 3]], [[0, 0, 1]] * 3, atol=1e-5)
    np.testing.assert_allclose(n[2], np.full(3, 1 / np.sqrt(3)), atol=1e-5)


def test_hit_distances_sign_by_inside_and_are_infinite_beyond_reach():
    body = _body()
    x = np.array([INSIDE, OUTSIDE, FAR], np.float32)
    d = hit_distances(body.query(x, 2.0))
    np.testing.assert_allclose(d[:2], [-0.2, 0.4], atol=1e-5)
    assert d[2] == np.inf


def test_face_normals_are_outward_and_twice_the_area_long():
    body = _body()
    n = face_normals(body, np.arange(12))
    centres = body.vertices[body.faces].mean(1)
    assert ((n * centres).sum(1) > 0).all()
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-6)  # half of a unit side


def test_on_skin_and_beyond_skin_of_points_inside():
    body = _body()
    x = np.array([INSIDE, [0.0, 0.0, 0.45], [0.0, 0.0, 0.0]])
    hit = body.query(x, 2.0, sign="normal")
    inside = hit.inside
    assert inside.all()
    # every one is inside, so none on the outer side of its closest face
    assert not on_skin(x[inside], body, hit, inside, reach=1.0).any()
    moved, direction = beyond_skin(x[inside], hit, inside, epsilon=0.01, body=body)
    np.testing.assert_allclose(direction[:2], [[0, 0, 1], [0, 0, 1]], atol=1e-6)
    np.testing.assert_allclose(moved[:2], [[0.1, -0.1, 0.51], [0.0, 0.0, 0.51]], atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(direction, axis=1), 1.0, atol=1e-6)


def test_a_point_on_the_skin_goes_out_along_its_face_not_along_rounding_noise():
    """A point the inside test counts in but that lies on the skin (distance 0 in float32,
    a few 1e-8 m from its closest point in float64): it goes epsilon out along its face's
    normal. Divided by its distance, the rounding sent such a vertex 24 m away."""
    body = _body()
    x = np.array([ON])
    hit = body.query(x, 2.0, sign="normal")
    hit.inside[:] = True  # as a winding number on the seam of two body parts may say
    hit.distance[:] = 0.0
    hit.points[:] = np.float32(x + [2.4e-8, 0.0, 0.0])  # the float32 closest point
    moved, direction = beyond_skin(x, hit, hit.inside, epsilon=0.01, body=body)
    np.testing.assert_allclose(direction, [[0, 0, 1]], atol=1e-6)
    np.testing.assert_allclose(moved, [[0.2, 0.1, 0.51]], atol=1e-6)


def test_on_skin_keeps_points_outside_within_reach():
    body = _body()
    x = np.array([OUTSIDE, [0.0, 0.0, 0.52]])
    hit = body.query(x, 2.0, sign="normal")
    every = np.ones(2, bool)
    assert on_skin(x, body, hit, every, reach=0.1).tolist() == [False, True]
    assert on_skin(x, body, hit, every, reach=1.0).tolist() == [True, True]
