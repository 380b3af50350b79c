"""The edge-length stage: the restorer's rounds, its solvers, the hanging edges."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from loosefit.errors import LoosefitInputError
from loosefit.inference.stages.lengths import (
    BAND_FRACTION,
    LengthConfig,
    LengthRestorer,
    hanging_edges,
)
from loosefit.model.losses import ClothStructure, signed_edge_change

TRI_FACES = np.array([[0, 1, 2]])
PAIR_FACES = np.array([[0, 1, 2], [1, 0, 3]])


def test_config_checks():
    with pytest.raises(LoosefitInputError, match="tie"):
        LengthConfig(tie=0.0)


def test_restore_lengths_undoes_a_uniform_shrink():
    # a 6 x 6 grid shrunk by 12 % about its fixed first row grows back to rest
    n = 6
    g = np.stack(np.meshgrid(np.arange(n), np.arange(n), indexing="ij"), -1).reshape(-1, 2)
    x = np.c_[g * 0.1, np.zeros(len(g))]
    faces = []
    for a in range(n - 1):
        for b in range(n - 1):
            v = a * n + b
            faces += [[v, v + n, v + 1], [v + 1, v + n, v + n + 1]]
    faces = np.array(faces)
    waist = np.arange(n)  # the row a = 0
    s = ClothStructure.from_mesh(x, faces, waist)
    shrunk = torch.tensor(x, dtype=torch.float64)
    shrunk = shrunk[0] + 0.88 * (shrunk - shrunk[0])
    shrunk[waist] = torch.tensor(x[waist])
    before = signed_edge_change(shrunk, s.edges, s.rest_lengths.double())
    restore = LengthRestorer(s, LengthConfig(iterations=30))
    out = restore(shrunk)
    after = signed_edge_change(out, s.edges, s.rest_lengths.double())
    assert float(before.median()) < -0.1
    assert float(after.abs().max()) < 0.01
    # ten rounds already bring the median edge back within 0.1 %
    ten = LengthRestorer(s, LengthConfig(iterations=10))(shrunk)
    assert abs(float(signed_edge_change(ten, s.edges, s.rest_lengths.double()).median())) < 1e-3
    assert torch.equal(out[waist], shrunk[waist])  # the waistband held
    # a garment at rest is left as it is, and a batch is taken frame by frame
    rest = torch.tensor(x)
    assert torch.allclose(restore(rest), rest, atol=1e-6)
    both = restore(torch.stack([shrunk, rest]))
    assert torch.allclose(both[0], out, atol=1e-6) and torch.allclose(both[1], rest, atol=1e-6)
    # gradients pass through the solves (checked against finite differences)
    y = shrunk[6:9].clone().requires_grad_(True)
    small = ClothStructure.from_mesh(x, faces, waist)

    def f(y):
        z = shrunk.clone()
        z[6:9] = y
        return LengthRestorer(small, LengthConfig(iterations=2))(z).pow(2).sum()

    assert torch.autograd.gradcheck(f, (y,), eps=1e-6, atol=1e-5)


def test_hanging_edges_are_the_steep_ones():
    # a triangle with a vertical edge (0-2), a horizontal one (0-1) and a 45-degree one
    x = np.array([[0.0, 0, 0], [1, 0, 0], [0, 0, -1]])
    s = ClothStructure.from_mesh(x, TRI_FACES)
    keep = hanging_edges(x, s.edges, 0.6)
    kept = {tuple(e) for e, k in zip(s.edges.tolist(), keep.tolist(), strict=True) if k}
    assert kept == {(0, 2), (1, 2)}  # |dz| / L: 1 and 0.71 kept, 0 not
    assert len(s.with_edges(keep).edges) == 2
    with pytest.raises(LoosefitInputError, match="edges"):
        LengthConfig(edges="some")


def test_the_host_rounds_and_the_differentiable_rounds_agree():
    # LengthRestorer runs its rounds in numpy without a gradient and in torch with one
    x = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0]])
    s = ClothStructure.from_mesh(x, PAIR_FACES, waist=np.array([0]))
    squeezed = torch.tensor(x * [0.8, 0.9, 1.0], dtype=torch.float64)
    restore = LengthRestorer(s, LengthConfig(iterations=5))
    host = restore(squeezed)
    grad = restore(squeezed.clone().requires_grad_(True)).detach()
    assert torch.allclose(host, grad, atol=1e-6)


def skirt(around: int, down: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A tube of ``down`` rings of ``around`` vertices (0.3 m radius, 3 cm apart) hanging
    from its top ring, about 1 m from the origin as a garment in the world is: (V, 3)
    vertices, (F, 3) faces, (around,) the waistband (the top ring)."""
    a = 2 * np.pi * np.arange(around) / around
    z = -0.03 * np.arange(down)
    ring = np.c_[0.3 * np.cos(a), 0.3 * np.sin(a)]
    x = np.concatenate([np.c_[ring, np.full(around, h)] for h in z]) + [0.5, 0.2, 1.0]
    faces = []
    for r in range(down - 1):
        for k in range(around):
            v, w = r * around + k, r * around + (k + 1) % around
            faces += [[v, v + around, w], [w, v + around, w + around]]
    return x, np.array(faces), np.arange(around)


def shrunk_frames(x: np.ndarray, waist: np.ndarray, frames: int) -> np.ndarray:
    """(frames, V, 3) float32: the rest shape shrunk 5-12 % towards the waist, jittered."""
    rng = np.random.default_rng(3)
    out = []
    for f in np.linspace(0.88, 0.95, frames):
        y = x[waist].mean(0) + f * (x - x[waist].mean(0)) + rng.normal(0, 2e-3, x.shape)
        y[waist] = x[waist]
        out.append(y)
    return np.array(out, np.float32)


def test_banded_rounds_match_superlu_and_float64():
    # a long skirt: its band (reverse Cuthill-McKee) is narrow against its size
    x, faces, waist = skirt(40, 30)
    s = ClothStructure.from_mesh(x, faces, waist)
    restore = LengthRestorer(s, LengthConfig(iterations=10))
    assert restore.banded is not None
    assert restore.banded.bandwidth <= BAND_FRACTION * len(restore.free)
    frames = shrunk_frames(x, waist, 8)
    banded = restore.restore_numpy(frames)
    restore.banded = None  # the same rounds by SuperLU
    lu = restore.restore_numpy(frames)
    assert np.abs(banded - lu).max() < 1e-6
    # and the differentiable rounds (float64 throughout)
    exact = restore(torch.tensor(frames, dtype=torch.float64, requires_grad=True)).detach()
    assert np.abs(banded - exact.numpy()).max() < 1e-6
    # the rounds did something: the shrink undone (the median edge within 0.5 % of rest)
    rest = s.rest_lengths.double()
    before = signed_edge_change(torch.tensor(frames).double(), s.edges, rest)
    after = signed_edge_change(torch.tensor(banded).double(), s.edges, rest)
    assert float(before.median()) < -0.04 and abs(float(after.median())) < 0.005


def test_a_wide_band_falls_back_to_superlu():
    # a short bag: two free rings of 40 and a bottom vertex joined to the lower one, so
    # that any order puts 20 of its neighbours on one side of it: a band of 20 or more,
    # wide against 81 unknowns
    x, faces, waist = skirt(40, 3)
    bottom = np.arange(80, 120)
    faces = np.r_[faces, np.c_[np.roll(bottom, -1), bottom, np.full(40, 120)]]
    x = np.r_[x, [x[bottom].mean(0) - [0, 0, 0.1]]]
    restore = LengthRestorer(ClothStructure.from_mesh(x, faces, waist), LengthConfig())
    assert restore.banded is None
    frames = shrunk_frames(x, waist, 2)
    host = restore.restore_numpy(frames)
    exact = restore(torch.tensor(frames, dtype=torch.float64, requires_grad=True)).detach()
    assert np.abs(host - exact.numpy()).max() < 1e-6
