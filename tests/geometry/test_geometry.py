import numpy as np
import torch

from loosefit.geometry.normals import face_normals, vertex_normals
from loosefit.geometry.query import Surface, closest_points
from loosefit.geometry.skinning import nearest_rotation, rigid_point_frames


def _naive_vertex_normals(v, f):
    out = np.zeros_like(v)
    for a, b, c in f:
        n = np.cross(v[b] - v[a], v[c] - v[a])
        for i in (a, b, c):
            out[i] += n
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def test_vertex_normals_match_naive_loop():
    rng = np.random.default_rng(0)
    v = rng.normal(size=(30, 3))
    f = np.array([rng.choice(30, 3, replace=False) for _ in range(60)])
    used = np.unique(f)
    got = vertex_normals(torch.from_numpy(v), torch.from_numpy(f)).numpy()
    assert np.allclose(got[used], _naive_vertex_normals(v, f)[used], atol=1e-10)


def test_face_normal_of_ccw_triangle_points_up():
    v = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    assert torch.allclose(face_normals(v, torch.tensor([[0, 1, 2]])), torch.tensor([[0.0, 0, 1]]))


def test_nearest_rotation_is_proper_and_exact_for_rotations():
    rng = np.random.default_rng(1)
    M = torch.from_numpy(rng.normal(size=(50, 3, 3)))
    R = nearest_rotation(M)
    assert torch.allclose(
        R @ R.transpose(-1, -2), torch.eye(3).double().expand(50, 3, 3), atol=1e-10
    )
    assert (torch.det(R) > 0).all()
    assert torch.allclose(nearest_rotation(R), R, atol=1e-10)


def test_rigid_point_frames_recover_a_rigid_motion():
    c, s = np.cos(0.7), np.sin(0.7)
    rot = torch.tensor([[c, -s, 0], [s, c, 0], [0, 0, 1]], dtype=torch.float32)
    T = torch.eye(4).repeat(1, 2, 1, 1)
    T[0, :, :3, :3] = rot
    T[0, :, :3, 3] = torch.tensor([1.0, 2.0, 3.0])
    pts = torch.randn(5, 3)
    w = torch.tensor([[0.3, 0.7]]).expand(5, 2)
    idx = torch.tensor([[0, 1]]).expand(5, 2)
    R, t = rigid_point_frames(T, w, idx, pts)
    assert torch.allclose(R[0], rot.expand(5, 3, 3), atol=1e-6)
    assert torch.allclose(t[0], torch.tensor([1.0, 2.0, 3.0]).expand(5, 3), atol=1e-5)


def _cube():
    v = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return v, np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])


def test_closest_points_on_a_cube():
    v, f = _cube()
    q = np.array([[0.5, 0.5, 0.9], [0.5, 0.5, 1.5], [-0.2, 0.5, 0.5]])
    hit = closest_points(v, f, q)
    assert hit.inside.tolist() == [True, False, False]
    assert np.allclose(hit.points, [[0.5, 0.5, 1.0], [0.5, 0.5, 1.0], [0.0, 0.5, 0.5]], atol=1e-6)
    assert np.allclose(hit.distance, [0.1, 0.5, 0.2], atol=1e-6)
    recon = (hit.barycentric[:, :, None] * v[f[hit.faces]]).sum(1)
    assert np.allclose(recon, hit.points, atol=1e-6)


def test_a_surface_answers_each_query_afresh():
    """Its arrays are kept from query to query: a smaller query after a larger one, and
    points beyond reach, get their own answers, nothing left over from the last."""
    v, f = _cube()
    surface = Surface(v, f)
    rng = np.random.default_rng(0)
    many = rng.uniform(-0.5, 1.5, (300, 3))
    first = surface.query(many, 2.0)
    few = np.array([[0.5, 0.5, 0.9], [5.0, 5.0, 5.0]])  # the second beyond reach
    hit = surface.query(few, 1.0)
    assert hit.faces.tolist()[1] == -1 and np.allclose(hit.points[1], 0.0)
    assert np.allclose(hit.barycentric[1], 0.0) and not hit.inside[1]
    assert np.allclose(hit.points[0], [0.5, 0.5, 1.0], atol=1e-6) and hit.inside[0]
    again = surface.query(many, 2.0)
    for a, b in zip(vars(first).values(), vars(again).values(), strict=True):
        assert np.array_equal(a, b)
    assert np.array_equal(first.faces, closest_points(v, f, many, 2.0).faces)
