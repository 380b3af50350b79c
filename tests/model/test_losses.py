"""The physics terms against values worked out by hand on tiny meshes."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from loosefit.errors import LoosefitInputError
from loosefit.model.losses import (
    ClothStructure,
    PhysicsLossConfig,
    bending_energy,
    collision_energy,
    dihedral_angles,
    hem_radius,
    membrane_energy,
    mesh_hinges,
    signed_edge_change,
    speed_error,
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
    x = np.array(
        [[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [5, 0, 0], [7, 0, 0], [5, 1, 0], [5, -1, 0]]
    )
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


def test_config_checks():
    with pytest.raises(LoosefitInputError, match="membrane"):
        PhysicsLossConfig(membrane=-1.0)
    assert PhysicsLossConfig(membrane=1.0, collision=0.5).active == ("membrane", "collision")


def test_hem_radius_by_hand():
    # a square hem of four vertices around the axis, 3 and 4 m out, and one vertex off it
    x = torch.tensor([[3.0, 0, -1], [0, 4, -1], [-3, 0, -1], [0, -4, -1], [9, 9, 0]])
    hem = torch.tensor([0, 1, 2, 3])
    assert float(hem_radius(x, hem)) == pytest.approx(3.5)
    # batched, and blind to height
    up = x + torch.tensor([0.0, 0, 2])
    assert hem_radius(torch.stack([x, up]), hem).tolist() == pytest.approx([3.5, 3.5])


def test_speed_error_by_hand():
    # two vertices: the truth steps 3 m and 0 m; the prediction steps 4 m (in another
    # direction) and 1 m: errors 1 and 1, mean square 1
    before = torch.zeros(2, 3)
    y = torch.tensor([[3.0, 0, 0], [0, 0, 0]])
    x = torch.tensor([[0.0, 4, 0], [0, 0, 1]])
    assert float(speed_error(x, before, y, before)) == pytest.approx(1.0)
    # the direction of a step is free: a turned step of the same length costs nothing
    assert float(speed_error(torch.tensor([[0.0, 3, 0], [0, 0, 0]]), before, y, before)) == 0.0
    # each garment steps from its own frame before; batched
    moved = before + 5.0
    batch = speed_error(torch.stack([x, y + 5.0]), torch.stack([before, moved]), y, before)
    assert batch.tolist() == pytest.approx([1.0, 0.0])
