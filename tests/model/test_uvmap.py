"""UV-map encoding: an analytic plane, seams, the default skirt, and bad layouts."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from loosefit.errors import LoosefitInputError
from loosefit.garment.skirt import SkirtConfig, make_skirt
from loosefit.garment.waist_fit import WaistFit
from loosefit.model.uvmap import UVMap, rasterize_uv
from loosefit.types import GarmentTemplate


def _grid(n: int = 9) -> GarmentTemplate:
    """A flat n x n grid of the unit square in z = 0, its UVs equal to its x, y."""
    x, y = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n), indexing="xy")
    v = np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], -1)
    f = []
    for r in range(n - 1):
        for c in range(n - 1):
            a = r * n + c
            f += [[a, a + 1, a + n + 1], [a, a + n + 1, a + n]]
    f = np.array(f)
    return GarmentTemplate(v, f, v[:, :2], f, np.arange(n))


WAIST = WaistFit(center=np.zeros(3), radii=np.array([0.16, 0.12]), height=0.0)


def test_plane_encodes_a_linear_function_exactly():
    plane = _grid()
    uv = UVMap(plane, 16)
    values = torch.from_numpy(plane.vertices)[None] * torch.tensor([2.0, -3.0, 0.0]) + 0.5
    maps = uv.encode(values)  # (1, 3, 16, 16)
    assert maps.shape == (1, 3, 16, 16)
    centres = (torch.arange(16) + 0.5) / 16
    expect_x = 2.0 * centres[None, :].expand(16, 16) + 0.5  # columns follow u = x
    expect_y = -3.0 * centres[:, None].expand(16, 16) + 0.5  # rows follow v = y
    assert uv.mask.all()  # the grid covers the whole square
    torch.testing.assert_close(maps[0, 0], expect_x)
    torch.testing.assert_close(maps[0, 1], expect_y)
    torch.testing.assert_close(maps[0, 2], torch.full((16, 16), 0.5))
    back = uv.sample(maps)
    # bilinear sampling of a linear function is exact away from the clamped border
    inner = (plane.vertices[:, :2] > 1 / 32).all(1) & (plane.vertices[:, :2] < 1 - 1 / 32).all(1)
    torch.testing.assert_close(back[0, inner], values[0, inner])
    assert (back - values).abs().max() < 2.0 / 16  # border: clamped to the outer texels


def test_sample_is_differentiable_and_batched():
    plane = _grid(5)
    uv = UVMap(plane, 8)
    maps = torch.randn(2, 4, 8, 8, dtype=torch.float64, requires_grad=True)
    assert uv.sample(maps).shape == (2, 25, 4)
    assert torch.autograd.gradcheck(lambda m: uv.sample(m), (maps,))


def test_seam_vertices_average_their_samples():
    skirt = make_skirt(SkirtConfig(style="aline", rings=6, segments=16), WAIST)
    uv = UVMap(skirt, 32)
    # every vertex used by a face on both sides of the seam has two UVs
    pairs = np.unique(np.stack([skirt.faces.ravel(), skirt.face_uvs.ravel()], 1), axis=0)
    seam = np.bincount(pairs[:, 0]) > 1
    assert seam.any()
    maps = uv.encode(torch.from_numpy(skirt.vertices)[None])
    back = uv.sample(maps)[0].numpy()
    err = np.linalg.norm(back - skirt.vertices, axis=-1)
    assert err[seam].max() < 0.02 and err.mean() < 0.005


def test_default_skirt_round_trip_is_submillimetre():
    skirt = make_skirt(SkirtConfig.preset("cpu", "flared"), WAIST)
    uv = UVMap(skirt, 64)
    v = torch.from_numpy(skirt.vertices)[None]
    err = (uv.sample(uv.encode(v)) - v).norm(dim=-1)
    assert err.mean() < 1e-3 and err.max() < 5e-3  # measured: 0.44 mm mean, 2.2 mm max


def test_bad_layouts_are_rejected():
    plane = _grid(3)
    with pytest.raises(LoosefitInputError, match="uvs"):
        rasterize_uv(plane.uvs * 1.5, plane.face_uvs, 8)
    overlapping = plane.face_uvs.copy()
    uvs = np.concatenate([plane.uvs, plane.uvs[:1] * 0 + 0.6])
    overlapping[0] = [len(uvs) - 1, overlapping[3, 1], overlapping[3, 2]]  # face 0 onto face 3
    with pytest.raises(LoosefitInputError, match="overlap"):
        rasterize_uv(uvs, overlapping, 16)
    with pytest.raises(LoosefitInputError, match="size"):
        UVMap(plane, 2)
    uv = UVMap(plane, 8)
    with pytest.raises(LoosefitInputError, match="values"):
        uv.encode(torch.zeros(1, 5, 3))
