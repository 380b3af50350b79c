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

:class:`LengthRestorer` is the other way to the same end, an output that keeps its edge
lengths by construction: a few local-global rounds of a mass-spring system (projective
dynamics) that bring every edge back to its rest length with the waistband held and the
shape kept, differentiable, batched.

Everything here is a pure function of tensors (any leading batch shape ``...``), except
:class:`ClothStructure`, which holds the rest quantities of one garment.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
import torch

from loosefit.errors import LoosefitInputError
from loosefit.garment.mesh_checks import unique_edges

# LengthRestorer solves its system by blocks of its banded Cholesky factor when the band
# (reverse Cuthill-McKee) is at most this fraction of the free vertices and at most
# BANDED_UP_TO wide (the blocks hold ~3 n b numbers: 2 MB in float32 for the skirt's
# 2,268 x 81); a wider band is left to SuperLU, whose fill does not grow with the band
BAND_FRACTION = 1 / 8
BANDED_UP_TO = 512

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

    membrane: float = 0.0
    bending: float = 0.0
    collision: float = 0.0
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
class LengthConfig:
    """:class:`LengthRestorer`: how many rounds, how strongly the network's shape holds."""

    edges: str = "hanging"  # which edges: "hanging" (at rest within ~53 degrees of vertical,
    #   |dz| / L > min_vertical) or "all". Restoring every edge of the decoders' averaged
    #   garment gives back its area as a bell (the folds it lost become flare: hem flare
    #   1.18-1.33x the simulation's on the spin and ballet 05_02); the hanging edges alone
    #   give back its length (flare 0.98-1.08x; bench/stage_account.py, docs/STAGE_ACCOUNT.md)
    min_vertical: float = 0.6
    iterations: int = 10  # local-global rounds (0: the stage does nothing)
    tie: float = 1.0e-3  # alpha: how strongly every vertex stays where the network put it
    compression_only: bool = False  # restore only edges shorter than rest (leave stretch)

    def __post_init__(self) -> None:
        if not (isinstance(self.iterations, int) and self.iterations >= 0):
            raise LoosefitInputError(
                "LengthConfig", "iterations", "an integer >= 0", self.iterations
            )
        if self.edges not in ("hanging", "all"):
            raise LoosefitInputError("LengthConfig", "edges", "'hanging' or 'all'", self.edges)
        v = self.min_vertical
        if not (isinstance(v, (int, float)) and 0 <= v < 1):
            raise LoosefitInputError("LengthConfig", "min_vertical", "a number in [0, 1)", v)
        t = self.tie
        if not (isinstance(t, (int, float)) and np.isfinite(t) and t > 0):
            raise LoosefitInputError("LengthConfig", "tie", "a positive number", t)
        if not isinstance(self.compression_only, bool):
            raise LoosefitInputError(
                "LengthConfig", "compression_only", "true or false", self.compression_only
            )


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
        fixed: (V,) bool, the vertices :class:`LengthRestorer` holds (the waistband).
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


def hanging_edges(vertices: np.ndarray, edges: torch.Tensor, min_vertical: float) -> torch.Tensor:
    """(E,) bool: the edges whose rest direction is steeper than ``min_vertical`` (|dz| / L)."""
    x = np.asarray(vertices, np.float64)
    e = edges.cpu().numpy()
    d = x[e[:, 0]] - x[e[:, 1]]
    return torch.from_numpy(np.abs(d[:, 2]) > min_vertical * np.linalg.norm(d, axis=1))


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


class LengthRestorer:
    """Edges moved back to their rest lengths with the shape kept: ``restore(x)``.

    Each of ``iterations`` rounds takes every edge's direction in the current shape and
    asks for its rest length along it (the local step), then finds the positions that
    come nearest those edge vectors, with the waistband held and every vertex weakly tied
    to where the network put it (the global step)::

        min_x  sum_e |x_i - x_j - L_e d_e|^2 + alpha sum_v |x_v - x0_v|^2

    a mass-spring system solved as projective dynamics solves it (Bouaziz et al. 2014;
    Liu et al. 2013): the global step's matrix ``B^T B + alpha I`` (``B`` the edge
    incidence, waistband columns out) is the same in every round and every frame, so it
    is factorised once and each round is one solve for all coordinates and frames: by
    blocks of its banded Cholesky factor, the free vertices taken in reverse
    Cuthill-McKee order (:mod:`loosefit.geometry.banded`), or by SuperLU where that band
    is too wide (:data:`BAND_FRACTION`, :data:`BANDED_UP_TO`). Unlike vertex-by-vertex
    strain limiting, one round moves the whole garment, so a uniform shrink of a few per
    cent is undone in a few rounds.

    Gradients pass through (the solve's backward is a solve with the same matrix), so
    the restorer can sit at the end of a decoder in training.

    Args:
        structure: the garment's edges, rest lengths and waistband.
        config: rounds and the tie ``alpha``.
    """

    def __init__(self, structure: ClothStructure, config: LengthConfig | None = None) -> None:
        import scipy.sparse as sp
        import scipy.sparse.linalg as spla

        from loosefit.geometry.banded import BlockBandedCholesky, band_order

        self.config = cfg = config or LengthConfig()
        self.structure = structure
        edges = structure.edges.cpu().numpy()
        fixed = structure.fixed.cpu().numpy()
        V, E = len(fixed), len(edges)
        rows = np.r_[np.arange(E), np.arange(E)]
        inc = sp.csr_matrix(
            (np.r_[np.ones(E), -np.ones(E)], (rows, edges.T.reshape(-1))), shape=(E, V)
        )
        free = np.flatnonzero(~fixed)
        tie = cfg.tie * sp.identity(len(free))
        bf = inc[:, free]
        order, width = band_order(bf.T @ bf + tie)
        self.free = free[order]  # (Vf,) the free vertices in band order: the system is banded
        self.held = np.flatnonzero(fixed)
        bf = inc[:, self.free]
        system = (bf.T @ bf + tie).tocsc()  # (Vf, Vf)
        # the differentiable rounds' solve (float64, its backward the same solve) and the
        # host rounds' where the band is too wide
        self._lu = spla.splu(system, permc_spec="MMD_AT_PLUS_A")
        # the host rounds' solve: float32 blocks (2 ms a round for the skirt's 64 frames
        # on one core, where the dense float32 inverse this replaces took 16 ms; float64
        # blocks take 5 ms). Their relative error (~2e-7; condition number ~1.5e3 for the
        # skirt at tie 1e-3) falls on each round's change, not on the positions
        # (restore_numpy; bench/notes/length_solve.py)
        narrow = width <= min(BAND_FRACTION * len(free), BANDED_UP_TO)
        self.banded = BlockBandedCholesky(system, np.float32) if narrow else None
        self._bf_t = bf.T.tocsr()  # (Vf, E)
        self._bh = inc[:, self.held].tocsr()  # (E, Vh)
        self._bf_t32 = self._bf_t.astype(np.float32)
        # the host rounds keep every vertex in one order, the free ones first (band
        # order) and then the held ones, so a round's solve fills rows :Vf
        self._order = np.r_[self.free, self.held]  # (V,)
        self._inc32 = inc[:, self._order].tocsr().astype(np.float32)  # (E, V) in that order
        self._rest32 = structure.rest_lengths.cpu().numpy().astype(np.float32)[:, None]  # (E, 1)

    def __call__(self, x: torch.Tensor) -> torch.Tensor:
        """(..., V, 3) positions -> (..., V, 3) with edges near rest; differentiable
        where ``x`` needs a gradient (otherwise the rounds run in numpy, on the host)."""
        if self.config.iterations == 0:
            return x
        if x.requires_grad and torch.is_grad_enabled():
            return self._torch(x)
        lead, V = x.shape[:-2], x.shape[-2]
        flat = x.detach().reshape(-1, V, 3)
        out = torch.from_numpy(self.restore_numpy(flat.cpu().numpy())).to(x.device, x.dtype)
        held = torch.from_numpy(self.held).to(x.device)
        out[:, held] = flat[:, held]  # exactly as given (the rounds run in float32)
        return out.reshape(*lead, V, 3)

    def restore_numpy(self, x: np.ndarray) -> np.ndarray:
        """(B, V, 3) -> (B, V, 3) float32: the rounds on the host (no gradient).

        Each round solves for the change of the free vertices, not their positions:
        ``x' = x + A^-1 (b - A x)`` with ``b - A x = B_f^T (t - d) + alpha (x0 - x)``, ``d``
        the current edge vectors and ``t`` their targets. The change is millimetres where
        the positions are metres, so the float32 solve's relative error costs ~1e-7 m
        instead of ~1e-5 m (the skirt on salsa 60_01: 4e-7 m from float64 throughout;
        the dense float32 inverse this replaces solved for positions and was 1e-5 m off).
        """
        cfg = self.config
        B, V, _ = x.shape
        Vf = len(self.free)
        # (V, 3*B) float32, vertices in the rounds' order (free in band order, then held);
        # the frames innermost, so that the per-edge arithmetic runs along them
        cur = np.asarray(x, np.float32).transpose(1, 2, 0)[self._order].reshape(V, 3 * B)
        x0f = cur[:Vf].copy()  # (Vf, 3*B) where the network put the free vertices
        tie = np.float32(cfg.tie)
        rest = self._rest32  # (E, 1)
        for _ in range(cfg.iterations):
            d = (self._inc32 @ cur).reshape(-1, 3, B)  # (E, 3, B) the edge vectors
            length = d[:, 0] * d[:, 0]  # (E, B)
            length += d[:, 1] * d[:, 1]
            length += d[:, 2] * d[:, 2]
            np.sqrt(length, out=length)
            np.maximum(length, 1e-12, out=length)
            scale = np.divide(rest, length, out=length)
            if cfg.compression_only:
                np.maximum(scale, 1.0, out=scale)
            scale -= 1
            d *= scale[:, None]  # t - d: each edge to its rest length along its direction
            residual = self._bf_t32 @ d.reshape(-1, 3 * B)  # (Vf, 3*B) b - A x
            residual += tie * (x0f - cur[:Vf])
            solver = self._lu if self.banded is None else self.banded
            cur[:Vf] += solver.solve(residual)
        out = np.empty((B, V, 3), np.float32)  # contiguous, vertices in their own order
        out[:, self._order] = cur.reshape(V, 3, B).transpose(2, 0, 1)
        return out

    def _torch(self, x: torch.Tensor) -> torch.Tensor:
        cfg = self.config
        lead = x.shape[:-2]
        V = x.shape[-2]
        flat = x.reshape(-1, V, 3)  # (B, V, 3)
        B = flat.shape[0]
        edges = self.structure.edges.to(x.device)
        rest = self.structure.rest_lengths.to(x.device, x.dtype)[:, None]
        free = torch.from_numpy(self.free).to(x.device)
        held = torch.from_numpy(self.held).to(x.device)
        x0f = flat[:, free]  # (B, Vf, 3)
        xh = flat[:, held]  # (B, Vh, 3)
        bf_t = _torch_sparse(self._bf_t, x)
        bh = _torch_sparse(self._bh, x)
        # the held vertices' share of every edge vector, fixed: B_h x_h
        held_part = torch.sparse.mm(bh, xh.permute(1, 0, 2).reshape(len(self.held), -1))
        cur = flat
        for _ in range(cfg.iterations):
            d = cur[:, edges[:, 0]] - cur[:, edges[:, 1]]  # (B, E, 3)
            length = d.norm(dim=-1, keepdim=True).clamp_min(1e-12)
            target = d * (rest / length)
            if cfg.compression_only:
                target = torch.where(length < rest, target, d)
            t = target.permute(1, 0, 2).reshape(len(edges), -1)  # (E, B*3)
            rhs = torch.sparse.mm(bf_t, t - held_part) + cfg.tie * x0f.permute(1, 0, 2).reshape(
                len(self.free), -1
            )
            sol = _SparseSolve.apply(rhs, self._lu).reshape(len(self.free), B, 3).permute(1, 0, 2)
            cur = flat.index_copy(1, free, sol)
        return cur.reshape(*lead, V, 3)


def _torch_sparse(m, like: torch.Tensor) -> torch.Tensor:
    m = m.tocoo()
    idx = torch.from_numpy(np.stack([m.row, m.col]).astype(np.int64))
    t = torch.sparse_coo_tensor(idx, torch.from_numpy(m.data), m.shape, check_invariants=False)
    return t.to(like.device, like.dtype).coalesce()


class _SparseSolve(torch.autograd.Function):
    """``A^-1 b`` for a factorised symmetric ``A`` (scipy's SuperLU), (N, K) -> (N, K)."""

    @staticmethod
    def forward(ctx, rhs: torch.Tensor, lu) -> torch.Tensor:
        ctx.lu = lu
        out = lu.solve(rhs.detach().cpu().double().numpy())
        return torch.from_numpy(out).to(rhs.device, rhs.dtype)

    @staticmethod
    def backward(ctx, grad: torch.Tensor):
        out = ctx.lu.solve(grad.detach().cpu().double().numpy())  # A symmetric: A^-T = A^-1
        return torch.from_numpy(out).to(grad.device, grad.dtype), None
