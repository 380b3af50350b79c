import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.geometry.edges import unique_edges
from loosefit.render.geometry import (
    NormalPlan,
    capsule,
    open_cone,
    smooth_vertex_normals,
    surface_of_revolution,
    uv_sphere,
)


def test_a_normal_plan_serves_every_frame_and_batch():
    v, f = uv_sphere(0.5, 12, 6)
    rng = np.random.default_rng(0)
    frames = v[None, None] + rng.normal(0, 0.02, (2, 3, len(v), 3)).astype(np.float32)
    plan = NormalPlan(f, len(v))
    got = plan(frames)
    assert got.shape == frames.shape and got.dtype == np.float32
    for b in range(2):
        for t in range(3):
            np.testing.assert_allclose(got[b, t], smooth_vertex_normals(frames[b, t], f), atol=1e-6)


def test_normals_keep_the_precision_of_their_vertices():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    f = np.array([[0, 1, 2]])
    n32 = smooth_vertex_normals(v, f)
    n64 = smooth_vertex_normals(v.astype(np.float64), f)
    assert n32.dtype == np.float32 and n64.dtype == np.float64
    np.testing.assert_array_equal(n32, [[0, 0, 1]] * 3)
    # integer corners are computed in float64; half precision is lifted to float32
    assert smooth_vertex_normals(v.astype(np.int32), f).dtype == np.float64
    assert smooth_vertex_normals(v.astype(np.float16), f).dtype == np.float32


def test_normals_refuse_vertices_of_the_wrong_shape():
    plan = NormalPlan(np.array([[0, 1, 2]]), 3)
    with pytest.raises(LoosefitInputError, match=r"shape \(\.\.\., 3, 3\).*shape \(4, 3\)"):
        plan(np.zeros((4, 3)))
    with pytest.raises(LoosefitInputError, match=r"expected shape \(\.\.\., V, 3\)"):
        smooth_vertex_normals(np.zeros((3, 2)), np.array([[0, 1, 2]]))
    with pytest.raises(LoosefitInputError, match="expected an integer array"):
        NormalPlan(np.array([[0.0, 1.0, 2.0]]), 3)


def test_a_revolved_profile_with_two_poles_is_closed():
    profile = np.array([[0.0, 0.0], [1.0, 0.5], [1.0, 1.5], [0.0, 2.0]])
    v, f = surface_of_revolution(profile, 8)
    assert v.shape == (2 * 8 + 2, 3) and f.dtype == np.int64
    _, counts = unique_edges(f)
    assert (counts == 2).all()  # every edge between two faces: no hole
    np.testing.assert_allclose(np.linalg.norm(v[:16, :2], axis=1), 1.0, atol=1e-6)
    np.testing.assert_allclose(v[-2:], [[0, 0, 0], [0, 0, 2]])
    # counter-clockwise seen from outside: the enclosed volume (divergence theorem) is positive
    a, b, c = (v[f[:, i]].astype(np.float64) for i in range(3))
    volume = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6
    assert volume > 0
    # every face, the poles' caps included, faces away from the middle (0, 0, 1)
    outward = np.einsum("ij,ij->i", np.cross(b - a, c - a), (a + b + c) / 3 - [0, 0, 1])
    assert (outward > 0).all()


def test_an_open_profile_leaves_both_ends_open():
    v, f = open_cone(0.2, 0.5, 1.0, 0.4, segments=10, rings=5)
    assert v.shape == (50, 3) and len(f) == 2 * 10 * 4
    _, counts = unique_edges(f)
    assert (counts == 1).sum() == 20  # the hem's and the waist's rings
    r = np.linalg.norm(v[:, :2], axis=1).reshape(5, 10)
    np.testing.assert_allclose(r[0], 0.5, atol=1e-6)
    np.testing.assert_allclose(r[-1], 0.2, atol=1e-6)
    np.testing.assert_allclose(v[:, 2].reshape(5, 10)[[0, -1], 0], [0.4, 1.0], atol=1e-6)


def test_sphere_and_capsule_sizes():
    v, f = uv_sphere(0.3, 16, 8, center=(1.0, 2.0, 3.0))
    assert len(v) == 16 * 7 + 2
    np.testing.assert_allclose(np.linalg.norm(v - [1.0, 2.0, 3.0], axis=1), 0.3, atol=1e-6)
    v, f = capsule(radius=0.1, height=1.5, segments=12, rings=16)
    np.testing.assert_allclose(v[:, 2].min(), 0.0, atol=1e-6)
    np.testing.assert_allclose(v[:, 2].max(), 1.5, atol=1e-6)
    assert np.linalg.norm(v[:, :2], axis=1).max() == pytest.approx(0.1, abs=1e-6)
    _, counts = unique_edges(f)
    assert (counts == 2).all()


def test_surface_of_revolution_refuses_a_short_profile_and_few_segments():
    with pytest.raises(LoosefitInputError, match=r"profile.*shape \(K>=2, 2\).*\(1, 2\)"):
        surface_of_revolution(np.array([[1.0, 0.0]]), 8)
    with pytest.raises(LoosefitInputError, match="segments': expected >= 3, found 2"):
        surface_of_revolution(np.array([[1.0, 0.0], [1.0, 1.0]]), 2)
