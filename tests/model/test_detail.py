"""The detail enhancement networks (paper 3.4): EdgeConv, patch sizes, losses, zero start."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch
from torch import nn
from torch_geometric.nn import EdgeConv

from loosefit.errors import LoosefitInputError
from loosefit.geometry.laplacian import Laplacian
from loosefit.model.detail import (
    DetailConfig,
    DetailGenerator,
    MultiScaleDiscriminator,
    cut_patches,
    detail_geometry_loss,
    edge_length_loss,
    lsgan_discriminator_loss,
    lsgan_generator_loss,
    mesh_edge_index,
    neighbour_table,
)
from tests.meshes import grid


def _grid(n: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """An n x n vertex grid in the plane z = 0 and its 2 (n-1)^2 triangles."""
    return grid(n, 0.0, 0.3)


def _edge_conv_loop(x: torch.Tensor, edge_index: torch.Tensor, mlp: nn.Module) -> torch.Tensor:
    """One EdgeConv layer as a plain loop over vertices: max_j mlp(x_i || x_j - x_i)."""
    src, dst = edge_index
    out = []
    for i in range(x.shape[0]):
        nbrs = src[dst == i]  # messages flow from source j to target i
        h = mlp(torch.cat([x[i].expand(len(nbrs), -1), x[nbrs] - x[i]], -1))
        out.append(h.max(0).values)
    return torch.stack(out)


def test_mesh_edges_are_each_edge_both_ways_once():
    v, f = _grid(3)
    e = mesh_edge_index(f)
    pairs = {tuple(p) for p in e.t().tolist()}
    assert len(pairs) == e.shape[1]  # no duplicates
    assert all((b, a) in pairs for a, b in pairs)
    # a 3x3 grid of two triangles per cell: 12 sides and 4 diagonals
    assert e.shape[1] == 2 * 16


def test_edge_conv_layers_match_a_plain_loop():
    torch.manual_seed(0)
    v, f = _grid(4)
    g = DetailGenerator(f, len(v), latent=8)
    x = torch.from_numpy(v) * g.config.scale + 0.1 * torch.randn(len(v), 3)
    for conv in g.convs:
        want = _edge_conv_loop(x, g.edge_index, conv.nn)
        got = conv(x[None])[0]
        torch.testing.assert_close(got, want)
        # and torch_geometric's own layer with the same MLP (its constructor re-initialises
        # the MLP it is given: a copy, with the weights put back)
        reference = EdgeConv(copy.deepcopy(conv.nn), aggr="max")
        reference.nn.load_state_dict(conv.nn.state_dict())
        torch.testing.assert_close(got, reference(x, g.edge_index))
        x = got


def test_the_neighbour_table_lists_each_vertex_neighbours():
    v, f = _grid(4)
    e = mesh_edge_index(f)
    table = neighbour_table(e, len(v))
    for i in range(len(v)):
        assert set(table[i].tolist()) == set(e[0, e[1] == i].tolist())
    with pytest.raises(LoosefitInputError, match="vertex 16 in none"):
        neighbour_table(e, len(v) + 1)


def test_generator_starts_at_zero_and_batches_like_single_frames():
    torch.manual_seed(0)
    v, f = _grid(5)
    g = DetailGenerator(f, len(v), latent=16)
    x = torch.from_numpy(v)[None].repeat(3, 1, 1) + 0.01 * torch.randn(3, len(v), 3)
    z = torch.randn(3, 16)
    assert torch.equal(g(x, z), torch.zeros(3, len(v), 3))  # an untrained module changes nothing
    nn.init.normal_(g.out.weight, std=0.1)
    both = g(x, z)
    one = torch.cat([g(x[i : i + 1], z[i : i + 1]) for i in range(3)])
    torch.testing.assert_close(both, one)
    assert both.abs().max() > 0


def test_generator_rejects_wrong_shapes():
    v, f = _grid(3)
    g = DetailGenerator(f, len(v), latent=4)
    with pytest.raises(LoosefitInputError, match="vertices"):
        g(torch.zeros(1, len(v) + 1, 3), torch.zeros(1, 4))
    with pytest.raises(LoosefitInputError, match="z"):
        g(torch.zeros(2, len(v), 3), torch.zeros(2, 5))


def test_discriminator_patch_sizes_and_score_shapes():
    d = MultiScaleDiscriminator(64)
    scores = d(torch.randn(2, 3, 64, 64))
    # 64-texel patches: 1 per map, scores 4x4; 32: 4 per map, 2x2; 16: 16 per map, 1x1
    assert [tuple(s.shape) for s in scores] == [(2, 1, 4, 4), (8, 1, 2, 2), (32, 1, 1, 1)]
    assert [net.net[0].stride for net in d.nets] == [(2, 2)] * 3
    assert sum(isinstance(m, nn.Conv2d) and m.stride == (2, 2) for m in d.nets[0].modules()) == 4
    with pytest.raises(LoosefitInputError, match="patches"):
        MultiScaleDiscriminator(48)


def test_patches_tile_the_map_and_are_centred():
    m = torch.arange(2 * 3 * 32 * 32, dtype=torch.float32).reshape(2, 3, 32, 32)
    p = cut_patches(m, 16)
    assert p.shape == (8, 3, 16, 16)
    torch.testing.assert_close(p.mean(dim=(2, 3)), torch.zeros(8, 3), atol=1e-3, rtol=0)
    # the first patch is the top-left corner of the first map, less its mean
    want = m[0, :, :16, :16] - m[0, :, :16, :16].mean(dim=(1, 2), keepdim=True)
    torch.testing.assert_close(p[0], want)


def test_geometry_loss_is_l1_of_positions_and_laplacians():
    v, f = _grid(4)
    lap = Laplacian(f, len(v))
    a = torch.from_numpy(v)[None]
    shift = a + torch.tensor([0.01, 0.0, 0.0])  # 1 cm along x: the Laplacian does not see it
    pos, lp = detail_geometry_loss(shift, a, lap)
    assert float(pos) == pytest.approx(1.0, rel=1e-4)
    assert float(lp) == pytest.approx(0.0, abs=1e-5)
    bump = a.clone()
    bump[0, 5, 2] += 0.01
    pos, lp = detail_geometry_loss(bump, a, lap)
    assert float(pos) == pytest.approx(1.0 / len(v), rel=1e-4)
    assert float(lp) > 0


def test_lsgan_losses():
    ones, minus = [torch.ones(4, 1, 2, 2)], [-torch.ones(4, 1, 2, 2)]
    assert float(lsgan_discriminator_loss(ones, minus)) == 0.0  # a perfect discriminator
    assert float(lsgan_discriminator_loss(minus, ones)) == 8.0
    assert float(lsgan_generator_loss(ones)) == 0.0  # fakes judged real
    assert float(lsgan_generator_loss(minus)) == 4.0


def test_config_checks():
    with pytest.raises(LoosefitInputError, match="patches"):
        DetailConfig(patches=(64, 24))
    with pytest.raises(LoosefitInputError, match="global_hidden"):
        DetailConfig(global_hidden=(8,))


def test_edge_length_loss_sees_stretch_but_not_rigid_motion():
    v, f = _grid(4)
    e = mesh_edge_index(f)
    e = e[:, e[0] < e[1]]
    x = torch.from_numpy(v)[None]
    turned = x @ torch.tensor([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]) + 0.5
    assert float(edge_length_loss(turned, x, e)) == pytest.approx(0.0, abs=1e-5)
    stretched = x * torch.tensor([1.1, 1.0, 1.0])
    lengths = (x[0, e[0]] - x[0, e[1]]).norm(dim=-1)
    grown = (stretched[0, e[0]] - stretched[0, e[1]]).norm(dim=-1)
    expected = 100 * float((grown - lengths).abs().mean())
    assert float(edge_length_loss(stretched, x, e)) == pytest.approx(expected, rel=1e-5)
    assert expected > 0.5  # cm: a 10 % stretch of 10 cm edges along x
