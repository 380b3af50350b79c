"""The edge-length stage: every hanging edge back to its rest length, the shape kept.

The decoders' garment is the mean of many fold configurations, whose edges are shorter
than any of them. :class:`LengthRestorer` brings the edges back by a few local-global
rounds of a mass-spring system (projective dynamics) with the waistband held and the
shape kept, differentiable and batched; :class:`LengthStage` runs it between the detail
stage and collision handling.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from loosefit.errors import LoosefitInputError
from loosefit.inference.stages import StageFrames
from loosefit.model.losses import ClothStructure
from loosefit.types import GarmentTemplate

# LengthRestorer solves its system by blocks of its banded Cholesky factor when the band
# (reverse Cuthill-McKee) is at most this fraction of the free vertices and at most
# BANDED_UP_TO wide (the blocks hold ~3 n b numbers: 2 MB in float32 for the skirt's
# 2,268 x 81); a wider band is left to SuperLU, whose fill does not grow with the band
BAND_FRACTION = 1 / 8
BANDED_UP_TO = 512


@dataclass
class LengthConfig:
    """:class:`LengthRestorer`: how many rounds, how strongly the network's shape holds (why
    only the hanging edges by default: docs/design/notes/lengths.md)."""

    edges: str = "hanging"  # which edges are restored: "hanging" (see min_vertical) or "all"
    min_vertical: float = 0.6  # a hanging edge's |dz| / L at rest exceeds this (~53 degrees)
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


def hanging_edges(vertices: np.ndarray, edges: torch.Tensor, min_vertical: float) -> torch.Tensor:
    """(E,) bool: the edges whose rest direction is steeper than ``min_vertical`` (|dz| / L)."""
    x = np.asarray(vertices, np.float64)
    e = edges.cpu().numpy()
    d = x[e[:, 0]] - x[e[:, 1]]
    return torch.from_numpy(np.abs(d[:, 2]) > min_vertical * np.linalg.norm(d, axis=1))


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
        # the host rounds' solve: float32 blocks, whose relative error falls on each
        # round's change, not on the positions (restore_numpy; the timings and the error:
        # docs/design/notes/lengths.md)
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


def length_restorer(template: GarmentTemplate, config: LengthConfig) -> LengthRestorer:
    """The edge-length operator of ``template``'s edges that ``config`` names (all of them,
    or the hanging ones)."""
    structure = ClothStructure.from_template(template)
    if config.edges == "hanging":
        structure = structure.with_edges(
            hanging_edges(template.vertices, structure.edges, config.min_vertical)
        )
    return LengthRestorer(structure, config)


class LengthStage:
    """The edge-length stage of a rollout: the frames' world garments with their edges back
    at rest length (:class:`LengthRestorer`, on the CPU)."""

    name = "lengths"

    def __init__(self, restorer: LengthRestorer) -> None:
        self.restorer = restorer

    def __call__(self, frames: StageFrames) -> torch.Tensor:
        """(n, V, 3) world garments, edges restored."""
        return self.restorer(frames.vertices)
