"""The physics terms against values worked out by hand on tiny meshes."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from loosefit.errors import LoosefitInputError
from loosefit.model.physics import (
    BAND_FRACTION,
    ClothStructure,
    LengthConfig,
    LengthRestorer,
    PhysicsLossConfig,
    bending_energy,
    collision_energy,
    dihedral_angles,
    hanging_edges,
    hem_radius,
    membrane_energy,
    mesh_hinges,
    signed_edge_change,
)

# a unit right triangle and a pair of triangles sharing the edge 0 -> 1
TRI = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
TRI_FACES = np.array([[0, 1, 2]])
PAIR = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0]])
PAIR_FACES = np.array([[0, 1, 2], [1, 0, 3]])


def test_hinges_of_a_pair():
    assert mesh_hinges(PAIR_FACES).tolist() == [[0, 1, 2, 3]]
    assert mesh_hinges(TRI_FACES).shape == (0, 4)  # a boundary edge is no hinge


def test_stretched_triangle_membrane_by_hand():
    s = ClothStructure.from_mesh(TRI, TRI_FACES)
    # stretch x by 1.5: edge 0-1 from 1 to 1.5 (strain 0.5), edge 0-2 unchanged (0),
    # edge 1-2 from sqrt(2) to sqrt(1.5^2 + 1) (strain sqrt(3.25 / 2) - 1)
    x = torch.tensor(TRI * [1.5, 1, 1], dtype=torch.float32)
    change = signed_edge_change(x, s.edges, s.rest_lengths)
    strains = {tuple(e): float(c) for e, c in zip(s.edges.tolist(), change, strict=True)}
    hyp = math.sqrt(3.25 / 2) - 1
    assert strains[(0, 1)] == pytest.approx(0.5, abs=1e-6)
    assert strains[(0, 2)] == pytest.approx(0.0, abs=1e-6)
    assert strains[(1, 2)] == pytest.approx(hyp, abs=1e-6)
    expected = (0.5**2 + 0 + hyp**2) / 3
    assert float(membrane_energy(x, s.edges, s.rest_lengths)) == pytest.approx(expected, rel=1e-5)
    # at rest, and moved rigidly, it is zero
    assert float(membrane_energy(torch.tensor(TRI).float(), s.edges, s.rest_lengths)) == 0.0
    R = torch.tensor([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    moved = torch.tensor(TRI).float() @ R.T + torch.tensor([3.0, -2, 5])
    assert float(membrane_energy(moved, s.edges, s.rest_lengths)) < 1e-12


def test_compressed_edges_cost_as_stretched_ones():
    s = ClothStructure.from_mesh(TRI, TRI_FACES)
    x = torch.tensor(TRI, dtype=torch.float32)
    assert float(membrane_energy(0.9 * x, s.edges, s.rest_lengths)) == pytest.approx(0.01, rel=1e-5)
    assert float(membrane_energy(1.1 * x, s.edges, s.rest_lengths)) == pytest.approx(0.01, rel=1e-5)


def folded(angle: float) -> torch.Tensor:
    """PAIR with the second face turned by ``angle`` about the shared edge (x axis)."""
    x = torch.tensor(PAIR, dtype=torch.float64)
    x[3] = torch.tensor([0.0, -math.cos(angle), math.sin(angle)], dtype=torch.float64)
    return x


@pytest.mark.parametrize("angle", [0.0, 0.3, math.pi / 2, 2.5])
def test_dihedral_angle_of_a_folded_pair(angle):
    hinges = torch.from_numpy(mesh_hinges(PAIR_FACES))
    # the second face folds up, to the side the first face's normal (+z) points to
    assert float(dihedral_angles(folded(angle), hinges)[0]) == pytest.approx(-angle, abs=1e-9)
    assert float(dihedral_angles(folded(-angle), hinges)[0]) == pytest.approx(angle, abs=1e-9)


def bend(x: torch.Tensor, s: ClothStructure) -> float:
    return float(bending_energy(x, s.hinges, s.rest_angles.double(), s.hinge_weights.double()))


def test_bending_energy_by_hand():
    s = ClothStructure.from_mesh(PAIR, PAIR_FACES)
    assert float(s.rest_angles[0]) == pytest.approx(0.0, abs=1e-7)
    # one hinge: the weighted mean is the squared angle itself
    assert bend(folded(math.pi / 2), s) == pytest.approx((math.pi / 2) ** 2, rel=1e-9)
    assert bend(folded(0.0), s) == pytest.approx(0.0, abs=1e-12)
    # a rest shape that is folded costs nothing as it is, and its flat state costs the fold
    r = ClothStructure.from_mesh(folded(0.4).numpy(), PAIR_FACES)
    assert bend(folded(0.4), r) == pytest.approx(0.0, abs=1e-10)
    assert bend(folded(0.0), r) == pytest.approx(0.16, rel=1e-5)


def test_bending_weights_discrete_shells():
    # two hinges: edge lengths 1 and 2 over the same faces' areas -> weights 1 : 4
    x = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0],
                  [5, 0, 0], [7, 0, 0], [5, 1, 0], [5, -1, 0]])  # fmt: skip
    f = np.array([[0, 1, 2], [1, 0, 3], [4, 5, 6], [5, 4, 7]])
    s = ClothStructure.from_mesh(x, f)
    w = s.hinge_weights.numpy()
    # |e|^2 / (A1 + A2): 1 / (0.5 + 0.5) = 1 and 4 / (1 + 1) = 2; normalised to mean 1
    assert w.tolist() == pytest.approx([2 / 3, 4 / 3])


def test_collision_energy_by_hand():
    points = torch.zeros(3, 3)
    normals = torch.tensor([[0.0, 0, 1], [0, 0, 1], [0, 0, 0]])  # the last: no body near
    x = torch.tensor([[0.0, 0, 0.01], [0, 0, -0.02], [0, 0, -1.0]])
    # eps 0.005: the first is clear (0), the second 0.025 short, the third not counted
    e = collision_energy(x, points, normals, 0.005)
    assert float(e) == pytest.approx(0.025**2 / 3, rel=1e-5)


def test_zero_length_edge_refused_by_name():
    x = np.array([[0.0, 0, 0], [0, 0, 0], [0, 1, 0]])
    with pytest.raises(LoosefitInputError) as err:
        ClothStructure.from_mesh(x, TRI_FACES, name="bad")
    msg = str(err.value)
    assert "bad" in msg and "zero-length" in msg and "vertices 0 and 1" in msg


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


def test_config_checks():
    with pytest.raises(LoosefitInputError, match="membrane"):
        PhysicsLossConfig(membrane=-1.0)
    with pytest.raises(LoosefitInputError, match="tie"):
        LengthConfig(tie=0.0)
    assert PhysicsLossConfig(membrane=1.0, collision=0.5).active == ("membrane", "collision")


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


def test_hem_radius_by_hand():
    # a square hem of four vertices around the axis, 3 and 4 m out, and one vertex off it
    x = torch.tensor([[3.0, 0, -1], [0, 4, -1], [-3, 0, -1], [0, -4, -1], [9, 9, 0]])
    hem = torch.tensor([0, 1, 2, 3])
    assert float(hem_radius(x, hem)) == pytest.approx(3.5)
    # batched, and blind to height
    up = x + torch.tensor([0.0, 0, 2])
    assert hem_radius(torch.stack([x, up]), hem).tolist() == pytest.approx([3.5, 3.5])
