"""The collision stage (paper 3.5): push a garment out of the body, its Laplacian kept.

For every garment vertex ``v_k`` the closest point ``b_k`` of the posed body and the
body's normal ``n_k`` there give the signed distance ``ds_k = n_k . (v_k - b_k)``. Eq. 16
asks for the garment ``V~`` nearest the predicted ``V`` in Laplacian coordinates with
every vertex at least ``eps`` outside::

    min_V~  || Delta(V) - Delta(V~) ||^2  +  sum_k max(eps - ds_k, 0)

Here ``V~ = V + D`` and the hinge is taken to its hard limit: every vertex of the
active set (each one that has had ``ds < eps``) is moved along its normal to ``eps``
outside (by ``(eps - ds_k) n_k``, no tangential motion; if it then finds another part
of the body closer and is still short of ``eps``, it is pushed on from there along
the new normal), and the other vertices within ``rings`` edges of one minimise the
Laplacian change::

    min_D  || L D ||^2 + mu || D ||^2   subject to  D_k = P_k  (k active, P_k its push)

by a direct sparse factorisation of that sub-system (one code path on CPU and CUDA:
the garment comes to the host once a frame, where the closest points are; no loop
over vertices; the coordinates decouple). The small anchor ``mu``
pins what the Laplacian cannot see (a translation of the whole garment is free in
Eq. 16 alone) and, with ``rings``, keeps a push local. The closest points of the
moved vertices are queried again after each solve (warp's BVH,
:class:`~loosefit.geometry.query.Surface`), since pushed vertices meet other parts
of the body, and the active set grows until no vertex is inside ``eps``.

Beyond the paper (:mod:`~loosefit.inference.stages.collision_finish`): a last projection by
the winding number (where body parts overlap the closest face's side misleads the solve),
bounded so that it never throws a vertex far (``finish``, ``finish_limit``), the tears
mended: pushes out of two body parts pressed together send neighbours to either side, and
edges stretched past ``stretch`` times their rest length are shortened and projected out
again (``relax``), and cloth deep in a limb kept to the side it left by (``sticky``).
docs/results/HARD_POSES.md; the figures behind the defaults: docs/design/notes/collision.md.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import torch
from scipy.linalg import solveh_banded

from loosefit.errors import LoosefitInputError
from loosefit.geometry.banded import band_order
from loosefit.geometry.edges import unique_edges
from loosefit.geometry.laplacian import laplacian_matrix
from loosefit.geometry.query import Surface
from loosefit.geometry.signed_distance import (
    normals_of_hit,
)
from loosefit.inference.stages import StageFrames
from loosefit.inference.stages.collision_finish import (
    last_projection,
    mend_tears,
    sticky_side,
)

if TYPE_CHECKING:
    from loosefit.inference.stages.push_out import PushOutHandler


@dataclass
class CollisionConfig:
    """Eq. 16 and its solver (why each default is what it is: docs/design/notes/collision.md)."""

    epsilon: float = 1.0e-3  # m: every vertex ends at least this far outside the body (eps)
    anchor: float = 1.0e-3  # mu: weight of ||D||^2 (the Laplacian's null space; locality)
    rings: int = 4  # a solve moves only vertices within this many edges of an active one
    iterations: int = 4  # closest-point queries and solves per frame, at most
    face_reach: float = 0.005  # m: faces with a vertex this near the body get points checked too
    reach: float = 0.1  # m: vertices farther than this from the body are never touched
    finish: int = 6  # rounds of the last projection (winding number inside: straight out to eps)
    finish_reach: float = 0.1  # m: the last projection asks about vertices the solve saw this near
    finish_limit: float = 0.1  # m: the farthest the last projection moves a vertex from the solve's
    stretch: float = 1.5  # longest an edge may end, times its rest length (or its length before)
    relax: int = 8  # rounds that mend edges torn past ``stretch`` (shorten, project out); 0: none
    winding_accuracy: float = 1.0  # the fast winding number's beta (warp's; larger: slower)
    whole_body: bool = True  # collide with the whole body, arms and hands included
    fast: bool = True  # banded Cholesky solves and ray-cast inside tests; False: SuperLU, warp's
    sticky: bool = True  # cloth inside the body leaves by the side it left by the frame before
    sticky_factor: float = 1.5  # ... if that side is at most this many times the closest skin's
    sticky_slack: float = 0.005  # m: ... plus this

    def __post_init__(self) -> None:
        for name in (
            "epsilon",
            "anchor",
            "reach",
            "face_reach",
            "finish_reach",
            "finish_limit",
            "winding_accuracy",
            "sticky_factor",
            "sticky_slack",
        ):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
                raise LoosefitInputError("CollisionConfig", name, "a positive number", value)
        if not (isinstance(self.relax, int) and self.relax >= 0):
            raise LoosefitInputError("CollisionConfig", "relax", "an integer >= 0", self.relax)
        for name in ("rings", "iterations"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 1):
                raise LoosefitInputError("CollisionConfig", name, "an integer >= 1", value)
        if not (isinstance(self.stretch, (int, float)) and self.stretch > 1.0):
            raise LoosefitInputError("CollisionConfig", "stretch", "a number > 1", self.stretch)
        if not (isinstance(self.finish, int) and self.finish >= 0):
            raise LoosefitInputError("CollisionConfig", "finish", "an integer >= 0", self.finish)
        for name in ("whole_body", "fast", "sticky"):
            if not isinstance(getattr(self, name), bool):
                raise LoosefitInputError(
                    "CollisionConfig", name, "true or false", getattr(self, name)
                )


# ``loosefit animate --collision realtime``: one solve, one round of the last projection and
# of the mending a frame (its measured cost and quality: docs/design/notes/collision.md)
REALTIME = {"iterations": 1, "finish": 1, "relax": 1}
COLLISION_SETTINGS = ("full", "realtime")


def collision_setting(config: CollisionConfig, setting: str) -> CollisionConfig:
    """``config`` as ``setting`` runs it: ``"full"`` as it is, ``"realtime"`` with
    :data:`REALTIME`'s rounds."""
    if setting not in COLLISION_SETTINGS:
        raise LoosefitInputError("collision", "setting", " or ".join(COLLISION_SETTINGS), setting)
    return config if setting == "full" else replace(config, **REALTIME)


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


class CollisionHandler:
    """The garment's operators for Eq. 16 (``L``, ``L^T L + mu I``, the edge adjacency).

    They are scipy sparse matrices on the host: every solve is a small sub-system (the
    vertices near a penetration), factorised directly (SuperLU), and the closest-point
    queries that feed it come back to the host anyway, so the garment goes there once
    per frame and comes back on its own device.

    Args:
        faces: (F, 3) the garment's triangles.
        num_vertices: V.
        config: Eq. 16's weights and the solver's limits.
        rest: (V, 3) the garment at rest, whose edge lengths ``stretch`` is measured against
            (None: each frame's input).
    """

    def __init__(
        self,
        faces: np.ndarray,
        num_vertices: int,
        config: CollisionConfig | None = None,
        rest: np.ndarray | None = None,
    ):
        self.config = config or CollisionConfig()
        self.num_vertices = V = num_vertices
        L = laplacian_matrix(faces, V, "uniform", dtype=torch.float64)
        (li, lj), lv = L.indices().numpy(), L.values().numpy()
        self.lap = sp.csr_matrix((lv, (li, lj)), shape=(V, V))
        self.ltl = (self.lap.T @ self.lap).tocsr()
        self.system = (self.ltl + self.config.anchor * sp.identity(V, format="csr")).tocsr()
        self.system.sort_indices()
        # the fast solve's order: reverse Cuthill-McKee of the whole system, so that any
        # sub-system taken in it is banded (a bandwidth of 40-80 for the skirt's)
        order, _ = band_order(self.system)
        self.rank = np.empty(V, np.int64)  # (V,) each vertex's place in that order
        self.rank[order] = np.arange(V)
        f = np.asarray(faces, np.int64)
        e, _ = unique_edges(f)
        self.edges = e  # (E, 2)
        if rest is not None and np.shape(rest) != (V, 3):
            raise LoosefitInputError(
                "CollisionHandler", "rest", f"({V}, 3) positions", f"{np.shape(rest)}"
            )
        self.rest_lengths = (
            None
            if rest is None
            # (E,) or None: the edges of the input
            else np.linalg.norm(rest[e[:, 0]] - rest[e[:, 1]], axis=1)
        )
        adj = sp.coo_matrix((np.ones(len(e), np.float32), (e[:, 0], e[:, 1])), shape=(V, V))
        self.adjacency = (adj + adj.T).tocsr()
        # points inside each face that must stay out too (a body edge between three
        # vertices that are outside pokes through the cloth): centroid and edge midpoints,
        # each midpoint asked once for the two faces that share its edge
        self.faces = f
        half = np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)  # (3F, 2)
        _, inverse = np.unique(half, axis=0, return_inverse=True)  # as unique_edges sorts
        self.face_edges = inverse.reshape(-1, 3)  # (F, 3) each face's edges, rows of edges
        # the last projection's inside test (Surface.query's sign)
        self.inside_test = "rays" if self.config.fast else "winding"
        # (V,) each vertex's closest body face when last asked (-1: none), the fast path's
        # hint for its next query (the same answer, from less of the BVH); kept from frame
        # to frame: a hint is only ever a bound, so a stale one costs time, never an answer
        self._face = np.full(V, -1, np.int64)
        # (V, 3) each vertex's closest body point when last asked (the fast path: the last
        # projection's first inside test reuses the solve's, at the same positions)
        self._closest = np.zeros((V, 3), np.float32)

    def laplacian(self, x: torch.Tensor) -> torch.Tensor:
        """(V, 3) -> (V, 3): the uniform Laplacian ``Delta`` of Eq. 16."""
        out = self.lap @ x.detach().cpu().double().numpy()
        return torch.from_numpy(out).to(x.device, x.dtype)

    def dilate(self, mask: np.ndarray, rings: int) -> np.ndarray:
        """(V,) bool grown by ``rings`` edges over the garment mesh."""
        out = mask.astype(np.float32)
        for _ in range(rings):
            out = np.maximum(out, (self.adjacency @ out > 0).astype(np.float32))
        return out > 0

    def resolve(
        self, garment: torch.Tensor, body: Surface, previous: np.ndarray | None = None
    ) -> CollisionResult:
        """One frame: the garment pushed out of the body (Eq. 16).

        Only the vertices within ``reach`` of the body are ever moved, and after each
        solve only the vertices it moved are queried again (the others' closest points
        have not changed).

        Args:
            garment: (V, 3) the predicted garment, world positions (m), on any device.
            body: the posed body's surface (refitted to this frame).
            previous: (V, 3) the way each vertex was moved out in the frame before, unit
                vectors (0: not moved), for ``sticky`` (None: no frame before).

        Returns:
            :class:`CollisionResult`, its vertices on the garment's device.
        """
        cfg = self.config
        V = self.num_vertices
        if garment.shape != (V, 3):
            raise LoosefitInputError(
                "CollisionHandler.resolve", "garment", f"({V}, 3)", f"{tuple(garment.shape)}"
            )
        x0 = garment.detach().cpu().double().numpy()
        d = np.zeros_like(x0)
        active = np.zeros(V, dtype=bool)
        region = np.zeros(V, dtype=bool)
        way = previous if cfg.sticky and previous is not None else None
        if way is not None and np.shape(way) != (V, 3):
            raise LoosefitInputError(
                "CollisionHandler.resolve", "previous", f"({V}, 3)", f"{np.shape(way)}"
            )
        n, ds = self._signed(x0, body, cfg.reach, slice(None))
        n, ds = sticky_side(self, x0, n, ds, way, body)
        iterations = 1
        depth_before = float(np.clip(cfg.epsilon - ds, 0, None).max())
        inside_before = int((ds < 0).sum())
        for _ in range(cfg.iterations):
            # the active set grows; a vertex once pushed stays held, and one still short
            # of eps (its closest point moved: another body part) is pushed on from where
            # it is along its new normal: the pushes add up (out of a crease of the body)
            short = np.clip(cfg.epsilon - ds, 0.0, None)  # (V,), 0 beyond reach
            push = short[:, None] * n  # (V, 3)
            # a point inside a face short of eps: its face's vertices take its push
            # (after a solve only the faces it moved: the others, and their answers, are
            # as before, and any of them that was short then pushed a vertex into the region)
            face_short = self._face_pushes(
                x0 + d, ds, body, short, push, region if iterations > 1 else None
            )
            if not (ds < 0.75 * cfg.epsilon).any() and not face_short:
                break
            active |= short > 0
            region |= self.dilate(active, cfg.rings)
            d = self._solve(d + push, active, region)
            # the moved vertices' closest points again: pushed ones meet other body parts
            moved = np.flatnonzero(region)
            at = x0[moved] + d[moved]
            n[moved], ds[moved] = sticky_side(
                self,
                at,
                *self._signed(at, body, cfg.reach, moved),
                None if way is None else way[moved],
                body,
            )
            iterations += 1
        x = x0 + d
        if not np.isfinite(x).all():  # cannot happen with SPD systems; never write NaN
            x, d = x0, np.zeros_like(x0)
            n, ds = self._signed(x, body, cfg.reach, slice(None))
        if cfg.finish:
            x, ds, passes = last_projection(self, x, ds, body)
            d = x - x0
            iterations += passes
        if cfg.relax:
            x, ds, passes = mend_tears(self, x0, x, ds, body)
            d = x - x0
            iterations += passes
        lap = self.lap @ d
        return CollisionResult(
            vertices=torch.from_numpy(x).to(garment.device, torch.float32),
            depth_before=depth_before,
            depth_after=float(np.clip(-ds, 0, None).max()),
            inside_before=inside_before,
            inside_after=int((ds < 0).sum()),
            moved=int((np.linalg.norm(d, axis=-1) > 1e-7).sum()),
            iterations=iterations,
            laplacian_change=float(np.sqrt((lap**2).sum(-1).mean())),
        )

    def _ask(self, x: np.ndarray, body: Surface, idx, sign: str, reach: float | None = None):
        """The closest points and inside test ``sign`` of the vertices ``idx`` (an index
        array or a slice) at ``x`` (N, 3), within ``reach`` (default: the config's); the
        fast path's hints from each vertex's closest face before, and noted for the next."""
        cfg = self.config
        reach = cfg.reach if reach is None else reach
        hint = self._face[idx] if cfg.fast else None
        hit = body.query(x, reach, sign=sign, accuracy=cfg.winding_accuracy, hint=hint)
        if cfg.fast:
            self._face[idx] = hit.faces
            self._closest[idx] = hit.points
        return hit

    def _signed(
        self, x: np.ndarray, body: Surface, reach: float, idx
    ) -> tuple[np.ndarray, np.ndarray]:
        """:func:`~loosefit.geometry.signed_distance.signed_distances` of the vertices
        ``idx`` at ``x`` (N, 3), with the fast path's hints (see :meth:`_ask`)."""
        return normals_of_hit(x, body, self._ask(x, body, idx, "normal", reach))

    def _face_pushes(
        self,
        x: np.ndarray,
        ds: np.ndarray,
        body: Surface,
        short: np.ndarray,
        push: np.ndarray,
        moved: np.ndarray | None = None,
    ) -> bool:
        """Check points inside the faces near the body (centroid, edge midpoints); where
        one is closer than ``0.75 eps``, the face's vertices that span it take its push
        (moving them all by it moves the point by it) when it is larger than their own.
        Updates ``short`` (V,) and ``push`` (V, 3) in place; True if any point was short.
        ``moved``: (V,) bool, only the faces with a vertex in it are checked (None: all).
        """
        cfg = self.config
        close = (ds[self.faces] < cfg.face_reach).any(1)  # (F,)
        if moved is not None:
            close &= moved[self.faces].any(1)
        near = np.flatnonzero(close)  # (Fn,)
        if not len(near):
            return False
        fv = self.faces[near]  # (Fn, 3)
        ev = self.edges[np.unique(self.face_edges[near])]  # (En, 2) their edges, each once
        # (Fn + En, 3) the samples: the faces' centroids, then the edges' midpoints
        # (the centroid as a weighted sum of the corners, rounded as it always was)
        centroids = np.einsum("k,fkd->fd", np.full(3, 1 / 3), x[fv])
        pts = np.concatenate([centroids, 0.5 * (x[ev[:, 0]] + x[ev[:, 1]])])
        # a point short of eps lies within the depth of its face's deepest vertex plus the
        # face_reach band: no farther query needed (a far reach costs the BVH walk)
        deepest = float(np.clip(-ds[fv].min(), 0.0, None))
        # the fast path's hints: the closest face of a vertex each point depends on
        hint = self._face[np.r_[fv[:, 0], ev[:, 0]]] if cfg.fast else None
        hit = body.query(
            pts, min(cfg.reach, deepest + 2 * cfg.face_reach), sign="normal", hint=hint
        )
        n, dp = normals_of_hit(pts, body, hit)
        bad = np.flatnonzero(dp < 0.75 * cfg.epsilon)
        if not len(bad):
            return False
        # each point short of eps: the vertices it depends on (a centroid's 3, a midpoint's 2)
        centroid = bad < len(fv)
        bc, be = bad[centroid], bad[~centroid]
        deficit = cfg.epsilon - dp  # (Fn + En,)
        v = np.r_[fv[bc].ravel(), ev[be - len(fv)].ravel()]  # (3 Bc + 2 Be,)
        dv = np.r_[np.repeat(deficit[bc], 3), np.repeat(deficit[be], 2)]
        nv = np.concatenate([np.repeat(n[bc], 3, axis=0), np.repeat(n[be], 2, axis=0)])
        order = np.argsort(dv)  # ascending: the largest push of a vertex is written last
        v, dv, nv = v[order], dv[order], nv[order]
        # a vertex inside the body keeps its own way out: a point of its face that is
        # nearer the far side of a limb (the hem deep in a thigh, its faces across the
        # middle) would send it through the limb, one side or the other from frame to frame
        own = (push[v] * nv).sum(1)  # (K,) short[v] times the cosine to its own push
        take = (dv > short[v]) & ((short[v] <= 0) | (own >= -1e-9 * short[v]))  # not against
        short[v[take]] = dv[take]
        push[v[take]] = dv[take, None] * nv[take]
        return True

    def _solve(self, pinned: np.ndarray, active: np.ndarray, region: np.ndarray) -> np.ndarray:
        """Minimise ``|L D|^2 + mu |D|^2`` with ``D_k`` given on the active vertices.

        The free unknowns are the region's other vertices (the rest keep ``D = 0``); the
        three coordinates decouple, so this is one sparse symmetric positive definite
        system ``(L^T L + mu I)_FF D_F = -(L^T L)_FA D_A`` with three right-hand sides,
        factorised once.

        Args:
            pinned: (V, 3) the displacements of the active vertices (others ignored).
            active: (V,) bool, the pinned vertices; region: (V,) bool, active ones included.

        Returns:
            (V, 3) the displacement.
        """
        d = np.zeros((self.num_vertices, 3))
        a = np.flatnonzero(active)
        d[a] = pinned[a]
        f = np.flatnonzero(region & ~active)
        if len(f) and self.config.fast:
            f = f[np.argsort(self.rank[f])]
            rhs = -(self.ltl @ d)[f]  # d is 0 off the active set: (L^T L)_FA D_A
            d[f] = solveh_banded(self._banded(f), rhs, lower=True, check_finite=False)
        elif len(f):
            rhs = -(self.ltl[f][:, a] @ d[a])
            lu = spla.splu(self.system[f][:, f].tocsc(), permc_spec="MMD_AT_PLUS_A")
            d[f] = lu.solve(rhs)
        return d

    def _banded(self, f: np.ndarray) -> np.ndarray:
        """The sub-system ``(L^T L + mu I)_FF`` of the free vertices ``f`` (n,) in lower
        banded storage (b + 1, n) for :func:`scipy.linalg.solveh_banded` (``ab[i - j, j]``
        holds entry (i, j), i >= j), read from the CSR arrays without building a matrix."""
        A = self.system
        pos = np.full(self.num_vertices, -1, np.int64)
        pos[f] = np.arange(len(f))
        starts, counts = A.indptr[f], np.diff(A.indptr)[f]
        # (nnz_F,) the entries of the rows f: each row's run of the CSR arrays
        take = np.repeat(starts - np.cumsum(counts) + counts, counts) + np.arange(counts.sum())
        row = np.repeat(np.arange(len(f)), counts)
        col = pos[A.indices[take]]
        keep = (col >= 0) & (col <= row)  # in the sub-system, on or below the diagonal
        row, col, val = row[keep], col[keep], A.data[take[keep]]
        ab = np.zeros((int((row - col).max()) + 1, len(f)))
        ab[row - col, col] = val
        return ab


class BodyCollider:
    """Collision handling along a motion, frame by frame: a ``collide(frame, garment)``
    callable that :class:`CollisionStage` runs.

    The body is posed lazily, ``chunk`` frames at a time, by ``pose(start, stop)``, and
    held in one BVH refitted to each frame.

    Args:
        handler: the garment's Eq. 16 operators (or the baseline's
            :class:`~loosefit.inference.stages.push_out.PushOutHandler`).
        body_faces: (F, 3) the collider's triangles (the simulation's collider).
        pose: ``pose(start, stop) -> (stop - start, Vb, 3)`` body vertices (m) of those
            motion frames.
        num_frames: T, the motion's frames.
        chunk: frames posed at once.
        device: warp device of the closest-point queries.
        winding_number: the body's BVH keeps the winding number (what the last projection
            asks: an arm pressed into the hip overlaps it); default: when the handler has
            a last projection that asks it (not the fast path's rays).
    """

    def __init__(
        self,
        handler: CollisionHandler | PushOutHandler,
        body_faces: np.ndarray,
        pose,
        num_frames: int,
        *,
        chunk: int = 64,
        device: str = "cpu",
        winding_number: bool | None = None,
    ) -> None:
        self.handler = handler
        if winding_number is None:
            winding_number = getattr(handler, "inside_test", None) == "winding" and bool(
                handler.config.finish
            )
        self.winding_number = winding_number
        self.faces = np.ascontiguousarray(np.asarray(body_faces), np.int64)
        self.pose = pose
        self.num_frames = num_frames
        self.chunk = chunk
        self.device = device
        self._start = -1
        self._body: np.ndarray | None = None
        self._surface: Surface | None = None
        self._last = -2  # the frame resolved last
        self._way: np.ndarray | None = None  # (V, 3) how each vertex was moved out there

    def body(self, frame: int) -> np.ndarray:
        """(Vb, 3) vertices of the posed body at a motion frame."""
        if not 0 <= frame < self.num_frames:
            raise IndexError(f"motion frame {frame} outside [0, {self.num_frames})")
        if self._body is None or not self._start <= frame < self._start + len(self._body):
            self._start = frame
            stop = min(frame + self.chunk, self.num_frames)
            self._body = np.asarray(self.pose(frame, stop), np.float32)
        return self._body[frame - self._start]

    def __call__(self, frame: int, garment: torch.Tensor) -> CollisionResult:
        """The garment (V, 3) at a motion frame, pushed out of the body there."""
        vertices = self.body(frame)
        if self._surface is None:
            self._surface = Surface(vertices, self.faces, self.device, self.winding_number)
        else:
            self._surface.refit(vertices)
        previous = self._way if frame == self._last + 1 else None
        result = self.handler.resolve(garment, self._surface, previous)
        # the way each vertex was moved out (unit; 0 where it moved less than a millimetre)
        moved = (result.vertices - garment.to(result.vertices.device)).detach().cpu().numpy()
        size = np.linalg.norm(moved, axis=1, keepdims=True)
        self._way = np.where(size > 1e-3, moved / np.maximum(size, 1e-12), 0.0)
        self._last = frame
        return result


def collision_record(result: CollisionResult) -> dict:
    """A collision result's figures, without its vertices."""
    return {k: v for k, v in vars(result).items() if k != "vertices"}


class CollisionStage:
    """The collision stage of a rollout: each frame's garment pushed out of the body by a
    ``collide(motion_frame, garment (V, 3)) -> CollisionResult`` (a :class:`BodyCollider`),
    frame by frame in motion order; each frame's figures kept in ``records``.

    Args:
        collide: the collider along the motion.
        device: where the garment goes to be resolved.
    """

    name = "collision"

    def __init__(self, collide, device: torch.device | str = "cpu") -> None:
        self.collide, self.device = collide, device
        self.records: list[dict] = []  # per motion frame resolved, collision_record's figures

    def __call__(self, frames: StageFrames) -> torch.Tensor:
        """(n, V, 3) world garments, pushed out of the body."""
        out = frames.vertices
        for i in range(len(out)):
            result = self.collide(frames.start + i, out[i].to(self.device))
            out[i] = result.vertices.cpu()
            self.records.append(collision_record(result))
        return out
