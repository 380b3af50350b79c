"""The baselines' collision post-process (Santesteban et al. 2019): a push-out, vertex by
vertex, the same ``resolve(garment, body)`` as Eq. 16's
:class:`~loosefit.inference.stages.collision.CollisionHandler`."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import torch

from loosefit.errors import LoosefitInputError
from loosefit.geometry.laplacian import laplacian_matrix
from loosefit.geometry.query import Surface
from loosefit.geometry.signed_distance import signed_distances
from loosefit.inference.stages.collision import CollisionResult


class PushOutHandler:
    """Santesteban et al. 2019's post-process: every vertex closer to the body than
    ``epsilon`` (or inside it) moved along the body's normal to ``epsilon`` outside,
    each on its own (no smoothness term: the baseline that Eq. 16 improves on).

    The same ``resolve(garment, body)`` as Eq. 16's handler, so
    :class:`~loosefit.inference.stages.collision.BodyCollider` runs either along a motion.

    Args:
        faces: (F, 3) the garment's triangles (for the Laplacian change it reports).
        num_vertices: V.
        epsilon: m, the clearance a moved vertex ends at.
        reach: m, vertices farther from the body are not queried.
    """

    def __init__(
        self, faces: np.ndarray, num_vertices: int, epsilon: float = 1.0e-3, reach: float = 0.1
    ) -> None:
        if not (np.isfinite(epsilon) and epsilon > 0 and np.isfinite(reach) and reach > 0):
            raise LoosefitInputError(
                "PushOutHandler", "epsilon, reach", "positive numbers", (epsilon, reach)
            )
        self.num_vertices, self.epsilon, self.reach = num_vertices, float(epsilon), float(reach)
        L = laplacian_matrix(faces, num_vertices, "uniform", dtype=torch.float64)
        (li, lj), lv = L.indices().numpy(), L.values().numpy()
        self.lap = sp.csr_matrix((lv, (li, lj)), shape=(num_vertices, num_vertices))

    def resolve(
        self, garment: torch.Tensor, body: Surface, previous: np.ndarray | None = None
    ) -> CollisionResult:
        """One frame: the garment (V, 3), world positions, with close vertices pushed out
        (each frame on its own: ``previous`` is not used)."""
        V = self.num_vertices
        if garment.shape != (V, 3):
            raise LoosefitInputError(
                "PushOutHandler.resolve", "garment", f"({V}, 3)", f"{tuple(garment.shape)}"
            )
        x0 = garment.detach().cpu().double().numpy()
        n, ds = signed_distances(x0, body, self.reach)
        short = np.clip(self.epsilon - ds, 0.0, None)  # (V,), 0 beyond reach
        d = short[:, None] * n
        x = x0 + d
        moved = short > 0
        ds_after = ds.copy()
        if moved.any():
            ds_after[moved] = signed_distances(x[moved], body, self.reach)[1]
        lap = self.lap @ d
        return CollisionResult(
            vertices=torch.from_numpy(x).to(garment.device, torch.float32),
            depth_before=float(short.max(initial=0.0)),
            depth_after=float(np.clip(-ds_after, 0, None).max()),
            inside_before=int((ds < 0).sum()),
            inside_after=int((ds_after < 0).sum()),
            moved=int(moved.sum()),
            iterations=2 if moved.any() else 1,
            laplacian_change=float(np.sqrt((lap**2).sum(-1).mean())),
        )
