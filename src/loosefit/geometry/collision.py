"""Collision handling (paper 3.5): push a garment out of the body while keeping its Laplacian.

For every garment vertex ``v_k`` the closest point ``b_k`` of the posed body and the
body's normal ``n_k`` there give the signed distance ``ds_k = n_k . (v_k - b_k)``. Eq. 16
asks for the garment ``V~`` nearest the predicted ``V`` in Laplacian coordinates with
every vertex at least ``eps`` outside::

    min_V~  || Delta(V) - Delta(V~) ||^2  +  sum_k max(eps - ds_k, 0)

Here ``V~ = V + D`` and the hinge is taken to its hard limit: every vertex of the
active set (each one that has had ``ds < eps``) is moved along its normal to ``eps``
outside (``n_k . D_k = c_k = eps - n_k . (V_k - b_k)``, no tangential motion), and the
other vertices within ``rings`` edges of one minimise the Laplacian change::

    min_D  || L D ||^2 + mu || D ||^2   subject to  D_k = c_k n_k  (k active)

by Jacobi-preconditioned conjugate gradients (all in torch: one code path on CPU
and CUDA, no loop over vertices; the coordinates decouple). The small anchor ``mu``
pins what the Laplacian cannot see (a translation of the whole garment is free in
Eq. 16 alone) and, with ``rings``, keeps a push local. The closest points are
queried again after each solve (warp's BVH,
:class:`~loosefit.geometry.query.Surface`), since pushed vertices meet other parts
of the body, and the active set grows until no vertex is inside ``eps``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import torch

from loosefit.errors import LoosefitInputError
from loosefit.geometry.laplacian import laplacian_matrix
from loosefit.geometry.normals import vertex_normals
from loosefit.geometry.query import Surface


@dataclass
class CollisionConfig:
    """Eq. 16 and its solver."""

    epsilon: float = 1.0e-3  # m: every vertex ends at least this far outside the body (eps)
    anchor: float = 1.0e-3  # mu: weight of ||D||^2 (the Laplacian's null space; locality)
    rings: int = 6  # a solve moves only vertices within this many edges of an active one
    iterations: int = 6  # closest-point queries and solves per frame, at most
    cg_iterations: int = 40  # conjugate-gradient steps per solve, at most
    cg_tolerance: float = 1.0e-3  # stop a solve at this preconditioned residual (relative)
    reach: float = 0.05  # m: vertices farther than this from the body are never touched

    def __post_init__(self) -> None:
        for name in ("epsilon", "anchor", "reach"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
                raise LoosefitInputError("CollisionConfig", name, "a positive number", value)
        for name in ("rings", "iterations", "cg_iterations"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 1):
                raise LoosefitInputError("CollisionConfig", name, "an integer >= 1", value)


@dataclass
class CollisionResult:
    """A garment frame after collision handling.

    Attributes:
        vertices: (V, 3) the resolved garment (the input where nothing penetrated).
        depth_before: m, the deepest vertex below ``epsilon`` outside the body before
            (``max(eps - ds)``, 0 when every vertex was already clear).
        depth_after: m, the same after: near 0 when resolved.
        inside_before, inside_after: vertices with ``ds < 0`` (inside the body).
        moved: vertices the solve moved.
        iterations: closest-point queries made.
        laplacian_change: m, the root mean square over the garment's vertices of
            ``|Delta(V~) - Delta(V)|``, what Eq. 16 keeps small.
    """

    vertices: torch.Tensor
    depth_before: float
    depth_after: float
    inside_before: int
    inside_after: int
    moved: int
    iterations: int
    laplacian_change: float


class CollisionHandler(torch.nn.Module):
    """The garment's operators for Eq. 16 (``L^T L`` and the edge adjacency) as buffers.

    Args:
        faces: (F, 3) the garment's triangles.
        num_vertices: V.
        config: Eq. 16's weights and the solver's limits.
    """

    def __init__(self, faces: np.ndarray, num_vertices: int, config: CollisionConfig | None = None):
        super().__init__()
        self.config = config or CollisionConfig()
        self.num_vertices = V = num_vertices
        L = laplacian_matrix(faces, V, "uniform", dtype=torch.float64)
        (li, lj), lv = L.indices().numpy(), L.values().numpy()
        Ls = sp.csr_matrix((lv, (li, lj)), shape=(V, V))
        LtL = (Ls.T @ Ls).tocsr()
        LtL.sort_indices()
        for name, m in (("ltl", LtL), ("lap", Ls)):  # CSR: ~16x faster products than COO on CPU
            self.register_buffer(f"{name}_crow", torch.from_numpy(m.indptr.astype(np.int64)),
                                 persistent=False)  # fmt: skip
            self.register_buffer(f"{name}_col", torch.from_numpy(m.indices.astype(np.int64)),
                                 persistent=False)  # fmt: skip
            self.register_buffer(f"{name}_values", torch.from_numpy(m.data.astype(np.float32)),
                                 persistent=False)  # fmt: skip
        self.register_buffer("ltl_diagonal", torch.from_numpy(LtL.diagonal().astype(np.float32)),
                             persistent=False)  # fmt: skip
        f = torch.as_tensor(np.asarray(faces), dtype=torch.long)
        e = torch.cat([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])  # (3F, 2)
        e = torch.cat([e, e.flip(1)]).unique(dim=0).t()  # (2, 2E) both directions
        self.register_buffer("adjacency", e, persistent=False)

    def _matrix(self, name: str) -> torch.Tensor:
        V = self.num_vertices
        with warnings.catch_warnings():  # "sparse CSR support is in beta": products are all we use
            warnings.simplefilter("ignore", UserWarning)
            return torch.sparse_csr_tensor(
                getattr(self, f"{name}_crow"), getattr(self, f"{name}_col"),
                getattr(self, f"{name}_values"), (V, V),
            )  # fmt: skip

    def laplacian(self, x: torch.Tensor) -> torch.Tensor:
        """(V, 3) -> (V, 3): the uniform Laplacian ``Delta`` of Eq. 16."""
        return self._matrix("lap") @ x

    def dilate(self, mask: torch.Tensor, rings: int) -> torch.Tensor:
        """(V,) bool grown by ``rings`` edges over the garment mesh."""
        out = mask.clone()
        src, dst = self.adjacency
        for _ in range(rings):
            grown = out.clone()
            grown[dst[out[src]]] = True
            out = grown
        return out

    def resolve(
        self,
        garment: torch.Tensor,
        body: Surface,
        body_normals: np.ndarray,
        body_faces: np.ndarray,
    ) -> CollisionResult:
        """One frame: the garment pushed out of the body (Eq. 16).

        Args:
            garment: (V, 3) the predicted garment, world positions (m), on this module's device.
            body: the posed body's surface (refitted to this frame).
            body_normals: (Vb, 3) unit vertex normals of the posed body.
            body_faces: (F, 3) the body surface's triangles (the faces ``body`` holds).

        Returns:
            :class:`CollisionResult`.
        """
        cfg = self.config
        V = self.num_vertices
        if garment.shape != (V, 3):
            raise LoosefitInputError("CollisionHandler.resolve", "garment", f"({V}, 3)",
                                     f"{tuple(garment.shape)}")  # fmt: skip
        x0 = garment.detach().float()
        dev = x0.device
        d = torch.zeros_like(x0)
        active = torch.zeros(V, dtype=torch.bool, device=dev)
        region = torch.zeros(V, dtype=torch.bool, device=dev)
        depth_before, inside_before = 0.0, 0
        iterations = 0
        for it in range(cfg.iterations + 1):
            # 1. closest body points, normals and signed distances of the current garment
            b, n, ds, valid = _signed_distances(x0 + d, body, body_normals, body_faces, cfg.reach)
            iterations += 1
            if it == 0:
                depth_before = float((cfg.epsilon - ds[valid]).clamp_min(0).max()) if valid.any() \
                    else 0.0  # fmt: skip
                inside_before = int((ds < 0).sum())
            violated = valid & (ds < cfg.epsilon - 0.25 * cfg.epsilon)
            if not violated.any() or it == cfg.iterations:
                break  # (b, n, ds, valid) are those of x0 + d
            # 2. the active set grows; a vertex once pushed stays held at eps
            active |= valid & (ds < cfg.epsilon)
            use = active & valid
            c = cfg.epsilon - (n * (x0 - b)).sum(-1)  # (V,) n . D_k must reach this
            region |= self.dilate(use, cfg.rings)
            # 3. the displacement: PCG on the region, the rest held where it is
            d = self._solve(d, n, c, use, region)
        x = x0 + d
        if not torch.isfinite(x).all():  # cannot happen with SPD systems; never write NaN
            x, d = x0, torch.zeros_like(x0)
            b, n, ds, valid = _signed_distances(x, body, body_normals, body_faces, cfg.reach)
        depth_after = float((-ds[valid]).clamp_min(0).max()) if valid.any() else 0.0
        lap = self.laplacian(d)
        return CollisionResult(
            vertices=x,
            depth_before=depth_before,
            depth_after=depth_after,
            inside_before=inside_before,
            inside_after=int((ds < 0).sum()),
            moved=int((d.norm(dim=-1) > 1e-7).sum()),
            iterations=iterations,
            laplacian_change=float(lap.pow(2).sum(-1).mean().sqrt()),
        )

    def _solve(
        self,
        d0: torch.Tensor,
        n: torch.Tensor,
        c: torch.Tensor,
        active: torch.Tensor,
        region: torch.Tensor,
    ) -> torch.Tensor:
        """Minimise ``|L D|^2 + mu |D|^2`` with ``D_k = c_k n_k`` on the active vertices.

        The free unknowns are the region's other vertices (the rest keep ``D = 0``); the
        three coordinates decouple, so this is one symmetric positive definite system
        with three right-hand sides, solved by Jacobi-preconditioned conjugate gradients
        from ``d0``.

        Args:
            d0: (V, 3) the start (the last solve's displacement).
            n: (V, 3) unit normals; c: (V,) how far each active vertex must move along n.
            active: (V,) bool, the pinned vertices; region: (V,) bool, active ones included.

        Returns:
            (V, 3) the displacement.
        """
        cfg = self.config
        mu = cfg.anchor
        ltl = self._matrix("ltl")
        pinned = c[:, None] * n * active[:, None]  # (V, 3)
        free = (region & ~active)[:, None].to(d0.dtype)  # (V, 1)

        def A(x: torch.Tensor) -> torch.Tensor:  # (V, 3) on the free vertices
            return free * (ltl @ x + mu * x)

        rhs = -A(pinned)
        inv_diag = free / (self.ltl_diagonal + mu)[:, None]
        x = d0 * free
        r = rhs - A(x)
        z = inv_diag * r
        p = z
        rz = (r * z).sum(0)  # (3,) one system per coordinate
        base = rz.abs().max() + 1e-30
        for _ in range(cfg.cg_iterations):
            if float(rz.abs().max()) < cfg.cg_tolerance**2 * base:
                break
            Ap = A(p)
            alpha = rz / (p * Ap).sum(0).clamp_min(1e-30)
            x = x + alpha * p
            r = r - alpha * Ap
            z = inv_diag * r
            rz_new = (r * z).sum(0)
            p = z + (rz_new / rz.clamp_min(1e-30)) * p
            rz = rz_new
        return pinned + x


def _signed_distances(
    x: torch.Tensor,
    body: Surface,
    body_normals: np.ndarray,
    body_faces: np.ndarray,
    reach: float,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Closest body points b (V, 3), normals n (V, 3), ``ds = n.(x - b)`` (V,) and a mask (V,)
    of the vertices within ``reach`` of the body. ``n`` is the distance's gradient, so
    ``ds = +-|x - b|`` (minus inside, by the closest face's side)."""
    dev = x.device
    hit = body.query(x.detach().cpu().numpy(), reach, sign="normal")
    valid = hit.faces >= 0
    corners = body_faces[np.where(valid, hit.faces, 0)]  # (V, 3) body vertex indices
    smooth = (body_normals[corners] * hit.barycentric[:, :, None]).sum(1)  # (V, 3)
    smooth /= np.maximum(np.linalg.norm(smooth, axis=-1, keepdims=True), 1e-12)
    # the distance's gradient (x - b)/|x - b|, turned outward for a point inside: exact at
    # the body's edges and corners; on the surface itself the interpolated normal
    side = np.where(hit.inside, -1.0, 1.0)[:, None]
    away = (np.asarray(x.detach().cpu().numpy(), np.float64) - hit.points) * side
    dist = hit.distance[:, None]
    nrm = np.where(dist > 1e-5, away / np.maximum(dist, 1e-12), smooth)
    b = torch.from_numpy(hit.points).to(dev)
    n = torch.from_numpy(nrm.astype(np.float32)).to(dev)
    ds = (n * (x - b)).sum(-1)
    v = torch.from_numpy(valid).to(dev)
    ds = torch.where(v, ds, torch.full_like(ds, float("inf")))
    return b, n, ds, v


def body_vertex_normals(vertices: np.ndarray | torch.Tensor, faces: np.ndarray) -> np.ndarray:
    """(..., Vb, 3) unit vertex normals of posed bodies (Vb, 3) or (T, Vb, 3), float32 numpy."""
    v = torch.as_tensor(np.asarray(vertices, np.float32))
    return vertex_normals(v, torch.as_tensor(np.asarray(faces), dtype=torch.long)).numpy()


class BodyCollider:
    """Collision handling along a motion, frame by frame: a ``collide(frame, garment)``
    callable for :func:`~loosefit.model.rollout.rollout`.

    The body is posed lazily, ``chunk`` frames at a time, by ``pose(start, stop)``, and
    held in one BVH refitted to each frame.

    Args:
        handler: the garment's Eq. 16 operators (on the device the garments come on).
        body_faces: (F, 3) the collider's triangles (the simulation's collider).
        pose: ``pose(start, stop) -> (stop - start, Vb, 3)`` body vertices (m) of those
            motion frames.
        num_frames: T, the motion's frames.
        chunk: frames posed at once.
        device: warp device of the closest-point queries.
    """

    def __init__(self, handler: CollisionHandler, body_faces: np.ndarray, pose, num_frames: int,
                 chunk: int = 64, device: str = "cpu") -> None:  # fmt: skip
        self.handler = handler
        self.faces = np.ascontiguousarray(np.asarray(body_faces), np.int64)
        self.pose = pose
        self.num_frames = num_frames
        self.chunk = chunk
        self.device = device
        self._start = -1
        self._body: np.ndarray | None = None
        self._normals: np.ndarray | None = None
        self._surface: Surface | None = None

    def body(self, frame: int) -> tuple[np.ndarray, np.ndarray]:
        """(Vb, 3) vertices and unit normals of the posed body at a motion frame."""
        if not 0 <= frame < self.num_frames:
            raise IndexError(f"motion frame {frame} outside [0, {self.num_frames})")
        if self._body is None or not self._start <= frame < self._start + len(self._body):
            self._start = frame
            stop = min(frame + self.chunk, self.num_frames)
            self._body = np.asarray(self.pose(frame, stop), np.float32)
            self._normals = body_vertex_normals(self._body, self.faces)
        k = frame - self._start
        return self._body[k], self._normals[k]

    def __call__(self, frame: int, garment: torch.Tensor) -> CollisionResult:
        """The garment (V, 3) at a motion frame, pushed out of the body there."""
        vertices, normals = self.body(frame)
        if self._surface is None:
            self._surface = Surface(vertices, self.faces, self.device)
        else:
            self._surface.refit(vertices)
        return self.handler.resolve(garment, self._surface, normals, self.faces)
