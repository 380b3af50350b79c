"""Physics terms for learned garments: membrane, bending, collision.

A network trained only on squared distances to a chaotic garment learns the mean of its
possible states, and the mean of many fold configurations has shorter edges and a smaller
hem than any of them (the committed salsa set: edges 10-13 % short of rest). The terms here
say what cloth is, whatever the data's mean, in the manner of the physics-based losses of
SNUG (Santesteban et al. 2022), Neural Cloth Simulation (Bertiche et al. 2022) and HOOD
(Grigorev et al. 2023), taken on edges and hinges of the garment mesh:

- **membrane**: ``mean_e (l_e / L_e - 1)^2``, every edge's length ``l_e`` against its rest
  length ``L_e`` (woven cloth hardly stretches, and compresses by folding, not by
  shortening its threads);
- **bending**: ``sum_h w_h (theta_h - Theta_h)^2 / sum_h w_h``, the signed dihedral angle
  of every interior edge against the rest shape's, weighted as discrete shells weight it
  (``w = |e|^2 / (A_1 + A_2)`` at rest);
- **collision**: ``mean_v max(eps - n_v . (x_v - b_v), 0)^2``, every vertex at least
  ``eps`` outside the body along the body's normal ``n_v`` at its point ``b_v``.

The edge-length stage (:class:`loosefit.inference.stages.lengths.LengthRestorer`) is the
other way to the same end, an output that keeps its edge lengths by construction.

Everything here is a pure function of tensors (any leading batch shape ``...``), except
:class:`ClothStructure`, which holds the rest quantities of one garment.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
import torch

from loosefit.errors import LoosefitInputError
from loosefit.geometry.edges import unique_edges

# the terms a checkpoint can have been trained with (the names of PhysicsLossConfig's weights)
PHYSICS_TERMS = ("membrane", "bending", "collision")


def active_terms(weights) -> tuple[str, ...]:
    """The physics terms a loss configuration (any object with their weights) turns on."""
    return tuple(t for t in PHYSICS_TERMS if getattr(weights, t, 0) > 0)


def terms_of(*checkpoints: dict) -> tuple[str, ...]:
    """The physics terms that stages' checkpoint dicts were trained with (their
    ``physics_terms``; a checkpoint from before the physics terms existed has none)."""
    found = set()
    for data in checkpoints:
        terms = data.get("physics_terms") or []
        found.update(str(t) for t in terms if str(t) in PHYSICS_TERMS)
    return tuple(t for t in PHYSICS_TERMS if t in found)


@dataclass
class PhysicsLossConfig:
    """Weights of the physics terms (0: off) and the collision clearance.

    The membrane and bending terms are dimensionless; the collision term is taken in the
    loss's length unit (``length_scale``, centimetres), as the squared errors are.
    """

    membrane: float = 0.0  # weight of the edge lengths against rest (dimensionless term)
    bending: float = 0.0  # weight of the dihedral angles against rest (dimensionless term)
    collision: float = 0.0  # weight of the cloth's depth inside the body (in length_scale)
    collision_epsilon: float = 0.002  # m: cloth closer to the body than this is penalised

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value >= 0):
                raise LoosefitInputError("PhysicsLossConfig", f.name, "a number >= 0", value)

    @property
    def active(self) -> tuple[str, ...]:
        """The terms with a positive weight."""
        return active_terms(self)


@dataclass
class ClothStructure:
    """A garment's edges and hinges with their rest quantities.

    Attributes:
        edges: (E, 2) int64 vertex pairs (the waistband's own edges left out: the body
            sets their length).
        rest_lengths: (E,) float32 metres, all positive.
        hinges: (H, 4) int64 ``(i, j, k, l)``: the interior edge ``(i, j)``, ``k`` the
            third corner of the face that runs ``i -> j``, ``l`` of the other face.
        rest_angles: (H,) float32 radians, the dihedral angles at rest.
        hinge_weights: (H,) float32 ``|e|^2 / (A_1 + A_2)`` at rest, normalised to mean 1.
        fixed: (V,) bool, the vertices
        :class:`~loosefit.inference.stages.lengths.LengthRestorer` holds (the waistband).
    """

    edges: torch.Tensor
    rest_lengths: torch.Tensor
    hinges: torch.Tensor
    rest_angles: torch.Tensor
    hinge_weights: torch.Tensor
    fixed: torch.Tensor

    @classmethod
    def from_mesh(
        cls,
        vertices: np.ndarray,
        faces: np.ndarray,
        waist: np.ndarray | None = None,
        name: str = "garment",
    ) -> ClothStructure:
        """The structure of a rest mesh.

        Args:
            vertices: (V, 3) rest positions (m).
            faces: (F, 3) triangles.
            waist: (W,) the waistband's vertices, or None.
            name: the garment's name, for errors.

        Raises:
            LoosefitInputError: an edge of zero rest length (two corners of a face at one
                place), named by its vertices: a length term would divide by it.
        """
        x = np.asarray(vertices, np.float64)
        f = np.asarray(faces, np.int64)
        waist = np.zeros(0, np.int64) if waist is None else np.asarray(waist, np.int64)
        edges, _ = unique_edges(f)
        rest = np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=-1)
        scale = max(float(np.ptp(x, axis=0).max()), 1e-30) if len(x) else 1.0
        zero = np.flatnonzero(rest <= 1e-9 * scale)
        if len(zero):
            i, j = edges[zero[0]]
            raise LoosefitInputError(
                f"garment '{name}'",
                "vertices",
                "edges of positive rest length (no two corners of a face at one place)",
                f"{len(zero)} zero-length edges, first between vertices {i} and {j}",
            )
        keep = ~np.isin(edges, waist).all(1)
        hinges = mesh_hinges(f)
        if len(hinges):
            xt = torch.from_numpy(x)
            angles = dihedral_angles(xt, torch.from_numpy(hinges)).numpy()
            e = x[hinges[:, 1]] - x[hinges[:, 0]]
            a1 = 0.5 * np.linalg.norm(np.cross(e, x[hinges[:, 2]] - x[hinges[:, 0]]), axis=-1)
            a2 = 0.5 * np.linalg.norm(np.cross(e, x[hinges[:, 3]] - x[hinges[:, 0]]), axis=-1)
            w = (e**2).sum(-1) / np.maximum(a1 + a2, 1e-30)
            w = w / w.mean()
        else:
            angles = w = np.zeros(0)
        fixed = np.zeros(len(x), bool)
        fixed[waist] = True
        return cls(
            edges=torch.from_numpy(edges[keep]),
            rest_lengths=torch.from_numpy(rest[keep]).float(),
            hinges=torch.from_numpy(hinges),
            rest_angles=torch.from_numpy(np.asarray(angles)).float(),
            hinge_weights=torch.from_numpy(np.asarray(w)).float(),
            fixed=torch.from_numpy(fixed),
        )

    @classmethod
    def from_template(cls, template) -> ClothStructure:
        """The structure of a :class:`~loosefit.types.GarmentTemplate` (its rest shape)."""
        return cls.from_mesh(template.rest, template.faces, template.waist, template.name)

    def to(self, device) -> ClothStructure:
        return ClothStructure(*(getattr(self, f.name).to(device) for f in fields(self)))

    def with_edges(self, keep: torch.Tensor) -> ClothStructure:
        """The same structure with only the edges ``keep`` (E,) bool."""
        return ClothStructure(
            self.edges[keep],
            self.rest_lengths[keep],
            self.hinges,
            self.rest_angles,
            self.hinge_weights,
            self.fixed,
        )


def mesh_hinges(faces: np.ndarray) -> np.ndarray:
    """(H, 4) int64 ``(i, j, k, l)`` of every edge shared by exactly two faces.

    ``k`` is the third corner of the first face (in face order) holding the edge, which
    runs ``i -> j`` in it, and ``l`` the third corner of the second. Edges of one face
    (the boundary) or of more than two are left out.
    """
    f = np.asarray(faces, np.int64)
    if not len(f):
        return np.zeros((0, 4), np.int64)
    # directed edges (a -> b) of every face and the corner opposite each
    a = f.reshape(-1)
    b = f[:, [1, 2, 0]].reshape(-1)
    c = f[:, [2, 0, 1]].reshape(-1)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = lo * (int(f.max()) + 1) + hi
    order = np.argsort(key, kind="stable")
    key_s = key[order]
    starts = np.flatnonzero(np.r_[True, key_s[1:] != key_s[:-1]])
    counts = np.diff(np.r_[starts, len(key_s)])
    two = starts[counts == 2]
    first, second = order[two], order[two + 1]
    return np.stack([a[first], b[first], c[first], c[second]], 1).astype(np.int64)


def signed_edge_change(x: torch.Tensor, edges: torch.Tensor, rest: torch.Tensor) -> torch.Tensor:
    """(..., V, 3) positions -> (..., E) ``length / rest - 1`` (negative: shorter)."""
    d = x[..., edges[:, 0], :] - x[..., edges[:, 1], :]
    return d.norm(dim=-1) / rest - 1.0


def hem_radius(x: torch.Tensor, hem: torch.Tensor) -> torch.Tensor:
    """(..., V, 3) -> (...): the hem's flare, the mean horizontal distance of the vertices
    ``hem`` (H,) from the vertical axis through the origin (+Z up; in the root frame, the
    axis through the root)."""
    return x[..., hem, :2].norm(dim=-1).mean(-1)


def speed_error(
    x: torch.Tensor, x_before: torch.Tensor, y: torch.Tensor, y_before: torch.Tensor
) -> torch.Tensor:
    """(..., V, 3) each -> (...): the mean over vertices of the squared difference of each
    vertex's speed (the length of its step from the frame before) between a prediction ``x``
    and the truth ``y``. It asks for the truth's energy, not its phase: a step of the right
    length in another direction costs nothing, a garment that moves less than the truth does.

    Args:
        x, x_before: the prediction and the garment it stepped from, in one frame.
        y, y_before: the truth and its frame before, in the same frame.
    """
    return ((x - x_before).norm(dim=-1) - (y - y_before).norm(dim=-1)).pow(2).mean(-1)


def membrane_energy(x: torch.Tensor, edges: torch.Tensor, rest: torch.Tensor) -> torch.Tensor:
    """(..., V, 3) -> (...): the mean over edges of the squared strain ``(l / L - 1)^2``."""
    return signed_edge_change(x, edges, rest).pow(2).mean(-1)


def dihedral_angles(x: torch.Tensor, hinges: torch.Tensor) -> torch.Tensor:
    """(..., V, 3) positions, (H, 4) hinges -> (..., H) signed dihedral angles (rad).

    0 where the two faces lie flat, within (-pi, pi]: negative where the second face
    folds toward the side the first face's normal points to (a valley seen from there),
    positive the other way (the sign of ``(n_1 x n_2) . (x_j - x_i)``).
    """
    xi, xj = x[..., hinges[:, 0], :], x[..., hinges[:, 1], :]
    xk, xl = x[..., hinges[:, 2], :], x[..., hinges[:, 3], :]
    e = xj - xi
    n1 = torch.linalg.cross(e, xk - xi)  # the first face's normal (i, j, k)
    n2 = torch.linalg.cross(xl - xi, e)  # the second face's (j, i, l)
    e_hat = e / e.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    sin = (torch.linalg.cross(n1, n2) * e_hat).sum(-1)
    cos = (n1 * n2).sum(-1)
    return torch.atan2(sin, cos)


def bending_energy(
    x: torch.Tensor, hinges: torch.Tensor, rest_angles: torch.Tensor, weights: torch.Tensor
) -> torch.Tensor:
    """(..., V, 3) -> (...): the weighted mean over hinges of ``(theta - Theta)^2``.

    The angle difference is wrapped into (-pi, pi], so a pair folded through flat the
    other way costs its true angle.
    """
    d = dihedral_angles(x, hinges) - rest_angles
    d = torch.remainder(d + torch.pi, 2 * torch.pi) - torch.pi
    return (weights * d.pow(2)).sum(-1) / weights.sum().clamp_min(1e-12)


def collision_energy(
    x: torch.Tensor, points: torch.Tensor, normals: torch.Tensor, epsilon: float
) -> torch.Tensor:
    """(..., V, 3) -> (...): the mean over vertices of ``max(eps - n . (x - b), 0)^2``.

    Args:
        x: (..., V, 3) garment positions.
        points: (..., V, 3) each vertex's point on the body ``b``.
        normals: (..., V, 3) the body's outward unit normal there ``n`` (0: no body near).
        epsilon: the clearance, in x's unit.
    """
    ds = (normals * (x - points)).sum(-1)
    near = normals.abs().sum(-1) > 0
    return (torch.relu(epsilon - ds) * near).pow(2).mean(-1)


def physics_terms(
    x: torch.Tensor,
    structure: ClothStructure,
    weights,
    contacts: tuple[torch.Tensor, torch.Tensor] | None = None,
    length_scale: float = 100.0,
) -> dict[str, torch.Tensor]:
    """The weighted physics terms of garments (..., V, 3), each (...,): those of ``weights``
    (any object with ``membrane``, ``bending``, ``collision`` and ``collision_epsilon``)
    above 0. ``contacts``: the body's points and normals (..., V, 3) each, needed by the
    collision term, which is taken in ``length_scale`` units (centimetres) as the squared
    errors are."""
    out = {}
    if weights.membrane > 0:
        out["membrane"] = weights.membrane * membrane_energy(
            x, structure.edges, structure.rest_lengths
        )
    if weights.bending > 0:
        out["bending"] = weights.bending * bending_energy(
            x, structure.hinges, structure.rest_angles, structure.hinge_weights
        )
    if weights.collision > 0:
        if contacts is None:
            raise ValueError("the collision term needs the body's points and normals")
        s = length_scale
        out["collision"] = weights.collision * collision_energy(
            s * x, s * contacts[0], contacts[1], s * weights.collision_epsilon
        )
    return out
