"""Linear blend skinning, the root frame's transforms and skinning weights taken from a body."""

from __future__ import annotations

import numpy as np
import pytest
import torch
import trimesh

from loosefit.errors import LoosefitInputError
from loosefit.geometry.skin_transfer import diffuse_weights, garment_skin_weights
from loosefit.geometry.skinning import dense_weights, linear_blend_skinning, root_frame_transforms
from tests.meshes import grid


def _random_transforms(g: torch.Generator, *shape: int) -> torch.Tensor:
    return torch.randn(*shape, 3, 4, generator=g, dtype=torch.float64)


def test_linear_blend_skinning_is_the_plain_loop_on_a_tiny_rig():
    g = torch.Generator().manual_seed(0)
    V, K, T = 5, 3, 2
    points = torch.randn(T, V, 3, generator=g, dtype=torch.float64)
    weights = torch.rand(V, K, generator=g, dtype=torch.float64)
    weights = weights / weights.sum(1, keepdim=True)
    A = _random_transforms(g, T, K)
    want = torch.zeros(T, V, 3, dtype=torch.float64)
    for t in range(T):
        for i in range(V):
            for k in range(K):
                want[t, i] += weights[i, k] * (A[t, k, :, :3] @ points[t, i] + A[t, k, :, 3])
    torch.testing.assert_close(linear_blend_skinning(points, weights, A), want)
    # a rest shape (V, 3) broadcasts over the frames
    torch.testing.assert_close(linear_blend_skinning(points[0], weights, A)[0], want[0])


def test_dense_weights_scatter_onto_their_joints():
    w = torch.tensor([[0.75, 0.25], [1.0, 0.0]])
    idx = torch.tensor([[2, 0], [1, 1]])
    torch.testing.assert_close(
        dense_weights(w, idx, 3), torch.tensor([[0.25, 0, 0.75], [0, 1.0, 0]])
    )


def test_root_frame_transforms_are_the_world_ones_seen_from_the_root_frame():
    g = torch.Generator().manual_seed(1)
    T, J = 3, 4
    world = torch.eye(4).repeat(T, J, 1, 1)
    world[..., :3, :] = _random_transforms(g, T, J).float()
    yaw = torch.tensor([0.3, -1.2, 2.0])
    c, s = torch.cos(yaw), torch.sin(yaw)
    H = torch.zeros(T, 3, 3)
    H[:, 0, 0], H[:, 0, 1], H[:, 1, 0], H[:, 1, 1], H[:, 2, 2] = c, -s, s, c, 1
    p = torch.randn(T, 3, generator=g)
    x = torch.randn(T, 3, generator=g)  # a rest point per frame
    got = root_frame_transforms(world, H, p)  # (T, J, 3, 4)
    for t in range(T):
        for j in range(J):
            x_world = world[t, j, :3, :3] @ x[t] + world[t, j, :3, 3]
            want = H[t].T @ (x_world - p[t])
            torch.testing.assert_close(
                got[t, j, :, :3] @ x[t] + got[t, j, :, 3], want, atol=1e-5, rtol=1e-5
            )


def test_far_vertices_get_the_harmonic_blend_of_the_near_ones():
    # a strip of 5 x 2 vertices; the two ends known with weights (1, 0) and (0, 1)
    v, f = grid(5, 0.0, 1.0)
    w = np.zeros((len(v), 2))
    known = np.zeros(len(v), bool)
    left, right = v[:, 0] == 0.0, v[:, 0] == 1.0
    known[left | right] = True
    w[left, 0] = 1.0
    w[right, 1] = 1.0
    out = diffuse_weights(w, f, known)
    np.testing.assert_allclose(out.sum(1), 1.0)
    np.testing.assert_allclose(out[known], w[known])
    # harmonic: every free vertex is the mean of its neighbours; weights grow left to right
    assert (np.diff(out[np.argsort(v[:, 0], kind="stable"), 1].reshape(5, 5).mean(1)) > 0).all()
    from loosefit.geometry.edges import unique_edges

    e, _ = unique_edges(f)
    for i in np.flatnonzero(~known):
        nb = np.r_[e[e[:, 0] == i, 1], e[e[:, 1] == i, 0]]
        np.testing.assert_allclose(out[i], out[nb].mean(0), atol=1e-9)


def test_garment_weights_from_a_two_bone_body():
    # a body: a box whose lower half is bone 0 and upper half bone 1; a sheet beside it
    box = trimesh.creation.box(extents=(0.2, 0.2, 1.0)).subdivide().subdivide().subdivide()
    bv, bf = np.asarray(box.vertices), np.asarray(box.faces)
    body_w = np.where(bv[:, 2:] > 0, [0.0, 1.0], [1.0, 0.0])  # (Vb, 2)
    v, f = grid(6, -0.5, 0.5)
    v = v[:, [2, 0, 1]] * np.float32([1, 0.18, 1]) + np.float32([0.11, 0, 0])  # 1 cm off a side
    v[v[:, 2] < 0, 0] += 0.3 * -v[v[:, 2] < 0, 2]  # the lower half flares away (a skirt's hem)
    w = garment_skin_weights(v, f, bv, bf, body_w, near=0.02)
    near = v[:, 0] <= 0.13
    np.testing.assert_allclose(w.sum(1), 1.0, atol=1e-6)
    top = near & (v[:, 2] > 0.2)  # faces straddling z = 0 blend the two bones
    np.testing.assert_allclose(w[top], [[0.0, 1.0]] * int(top.sum()), atol=1e-6)
    assert (w[~near, 1] > 0).all()  # the flared hem takes some of the upper bone, diffused
    with pytest.raises(LoosefitInputError, match="within 0.02 m"):
        garment_skin_weights(v + np.float32([1, 0, 0]), f, bv, bf, body_w, near=0.02)
