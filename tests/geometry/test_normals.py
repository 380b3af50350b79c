import numpy as np
import torch

from loosefit.geometry.normals import face_normals, vertex_normals
from tests.meshes import cube, grid


def test_face_normal_is_twice_the_area_long():
    v = torch.tensor([[0.0, 0, 0], [2, 0, 0], [0, 3, 0]])
    n = face_normals(v, torch.tensor([[0, 1, 2], [0, 2, 1]]))
    torch.testing.assert_close(n, torch.tensor([[0.0, 0, 6], [0, 0, -6]]))


def test_batched_normals_are_the_per_frame_ones():
    rng = np.random.default_rng(3)
    v = torch.from_numpy(rng.normal(size=(2, 4, 12, 3)))  # (B, T, V, 3)
    f = torch.from_numpy(np.array([rng.choice(12, 3, replace=False) for _ in range(20)]))
    fn, vn = face_normals(v, f), vertex_normals(v, f)
    assert fn.shape == (2, 4, 20, 3) and vn.shape == (2, 4, 12, 3)
    for b in range(2):
        for t in range(4):
            torch.testing.assert_close(fn[b, t], face_normals(v[b, t], f))
            torch.testing.assert_close(vn[b, t], vertex_normals(v[b, t], f))


def test_a_flat_grid_has_one_normal_and_an_unused_vertex_none():
    v, f = grid(4, 0.0, 1.0)
    v = torch.from_numpy(np.concatenate([v, [[5.0, 5.0, 5.0]]]).astype(np.float32))
    n = vertex_normals(v, torch.from_numpy(f))
    torch.testing.assert_close(n[:-1], torch.tensor([0.0, 0.0, -1.0]).expand(16, 3))
    torch.testing.assert_close(n[-1], torch.zeros(3))


def test_cube_normals_point_outward():
    v, f = cube()
    v = torch.from_numpy(v).double()
    n = vertex_normals(v, torch.from_numpy(f))
    torch.testing.assert_close(n.norm(dim=-1), torch.ones(8, dtype=torch.float64))
    assert ((n * v).sum(-1) > 0).all()  # every corner's normal leans away from the centre
    centres = v[torch.from_numpy(f)].mean(1)  # (F, 3)
    assert ((face_normals(v, torch.from_numpy(f)) * centres).sum(-1) > 0).all()


def test_vertex_normals_have_gradients():
    v, f = grid(3, 0.0, 1.0)
    v = torch.from_numpy(v).double()
    v[4, 2] = 0.3  # the middle vertex lifted: a tent
    v.requires_grad_(True)
    f = torch.from_numpy(f)
    assert torch.autograd.gradcheck(lambda x: vertex_normals(x, f), (v,))
