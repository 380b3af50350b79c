"""Mesh Laplacian ``Delta`` of the paper's losses (Eqs. 6, 10, 13, 16) as a sparse matrix.

``L`` is the normalised ("random walk") Laplacian: row ``i`` gives
``(L @ X)_i = X_i - sum_j w_ij X_j / sum_j w_ij`` over the 1-ring of ``i``, with
``w_ij = 1`` (uniform, the "umbrella" operator) or the cotangent weights of a
rest shape. Rows sum to 0, so constants map to 0; isolated vertices (in no
face) get an all-zero row.

The matrix is built once from the (fixed) topology and applied to any number
of shapes with :func:`apply_laplacian`, a sparse matmul differentiable with
respect to the shapes.
"""

from __future__ import annotations

import numpy as np
import torch

from loosefit.errors import LoosefitInputError

LAPLACIAN_KINDS = ("uniform", "cotangent")

# Cotangent edge weights below this (an edge facing obtuse angles: negative
# weight) are raised to it, so every row stays a convex average of the 1-ring.
MIN_COTANGENT_WEIGHT = 1e-4


def _as_long_tensor(faces: np.ndarray | torch.Tensor) -> torch.Tensor:
    if isinstance(faces, np.ndarray):
        faces = torch.from_numpy(faces)
    return faces.detach().to("cpu", torch.long)


def _edge_weights(
    faces: torch.Tensor, kind: str, vertices: torch.Tensor | None
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Directed half-edges (rows, cols) of every face corner and their weights (float64)."""
    # Corner k of a face is opposite the edge (a, b) = (faces[:, k+1], faces[:, k+2]).
    a = faces[:, [1, 2, 0]].reshape(-1)  # (3F,)
    b = faces[:, [2, 0, 1]].reshape(-1)  # (3F,)
    if kind == "uniform":
        w = torch.ones(a.shape[0], dtype=torch.float64)
    else:
        v = vertices.detach().to("cpu", torch.float64)
        corner = v[faces]  # (F, 3, 3): the face's three vertices
        u = corner[:, [1, 2, 0]] - corner  # (F, 3, 3) corner k -> a
        s = corner[:, [2, 0, 1]] - corner  # (F, 3, 3) corner k -> b
        cross = torch.linalg.vector_norm(torch.linalg.cross(u, s, dim=-1), dim=-1)  # (F, 3)
        # cot of the angle at corner k; zero-area faces would divide by 0: they get huge weights.
        w = (0.5 * (u * s).sum(-1) / cross.clamp_min(1e-300)).reshape(-1)  # (3F,)
    # Both directions: edge (a, b) contributes to row a and to row b.
    rows = torch.cat([a, b])
    cols = torch.cat([b, a])
    return rows, cols, torch.cat([w, w])


def laplacian_matrix(
    faces: np.ndarray | torch.Tensor,
    num_vertices: int,
    kind: str = "uniform",
    vertices: np.ndarray | torch.Tensor | None = None,
    dtype: torch.dtype = torch.float32,
) -> torch.Tensor:
    """The normalised mesh Laplacian as a sparse (V, V) COO matrix.

    ``(L @ X)_i = X_i - sum_j w_ij X_j / sum_j w_ij`` over the neighbours ``j`` of ``i``:

    - ``kind="uniform"``: ``w_ij = 1``, i.e. ``X_i`` minus the mean of its 1-ring.
    - ``kind="cotangent"``: ``w_ij = (cot alpha_ij + cot beta_ij) / 2``, the angles
      opposite edge ``ij`` in the rest shape ``vertices`` (one angle on a boundary
      edge). A weight below :data:`MIN_COTANGENT_WEIGHT` (an edge opposite obtuse
      angles, which can make it negative) is clamped to that small positive value,
      so each row stays a convex average; zero-area faces give huge weights.

    Args:
        faces: (F, 3) integer triangles, numpy or torch.
        num_vertices: V; vertices in no face get an all-zero row.
        kind: "uniform" or "cotangent".
        vertices: (V, 3) rest positions, required for ``kind="cotangent"``.
        dtype: floating dtype of the matrix (weights are computed in float64).

    Returns:
        (V, V) coalesced sparse COO tensor on the CPU; move it once to where it
        is used (:func:`apply_laplacian` would otherwise copy it on every call).
    """
    if kind not in LAPLACIAN_KINDS:
        raise LoosefitInputError(
            "laplacian_matrix", "kind", f"one of {LAPLACIAN_KINDS}", repr(kind)
        )
    f = _as_long_tensor(faces)
    if f.ndim != 2 or f.shape[1] != 3:
        raise LoosefitInputError("laplacian_matrix", "faces", "shape (F, 3)", f"{tuple(f.shape)}")
    if f.numel() and (int(f.min()) < 0 or int(f.max()) >= num_vertices):
        raise LoosefitInputError(
            "laplacian_matrix",
            "faces",
            f"vertex indices in [0, {num_vertices})",
            f"indices in [{int(f.min())}, {int(f.max())}]",
        )
    if kind == "cotangent":
        if vertices is None:
            raise LoosefitInputError(
                "laplacian_matrix", "vertices", "(V, 3) rest positions for kind='cotangent'", "None"
            )
        if isinstance(vertices, np.ndarray):
            vertices = torch.from_numpy(vertices)
        if tuple(vertices.shape) != (num_vertices, 3):
            raise LoosefitInputError(
                "laplacian_matrix",
                "vertices",
                f"shape ({num_vertices}, 3)",
                f"{tuple(vertices.shape)}",
            )

    rows, cols, w = _edge_weights(f, kind, vertices)
    V = num_vertices
    # Indices are checked above: invariant checks off (passing it also silences torch's warning).
    W = torch.sparse_coo_tensor(
        torch.stack([rows, cols]), w, (V, V), check_invariants=False
    ).coalesce()  # sums the duplicates
    (r, c), w = W.indices(), W.values()  # each undirected edge once per direction
    if kind == "uniform":
        w = torch.ones_like(w)  # an interior edge was counted twice (two faces)
    else:
        w = w.clamp_min(MIN_COTANGENT_WEIGHT)
    degree = torch.zeros(V, dtype=torch.float64).index_add_(0, r, w)  # (V,)
    has_ring = degree > 0
    diag = torch.nonzero(has_ring)[:, 0]
    indices = torch.cat([torch.stack([r, c]), torch.stack([diag, diag])], 1)  # (2, nnz)
    values = torch.cat([-w / degree[r], torch.ones(diag.shape[0], dtype=torch.float64)])
    return torch.sparse_coo_tensor(
        indices, values.to(dtype), (V, V), check_invariants=False
    ).coalesce()


def apply_laplacian(L: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """``L @ x`` for a batch of shapes, differentiable with respect to ``x``.

    Runs on ``x``'s device and dtype. ``L`` is converted to them when they
    differ, a copy on every call: callers should keep ``L`` on the right device
    (e.g. with :class:`Laplacian`, a module that moves with ``.to()``).

    Args:
        L: (V, V) sparse matrix from :func:`laplacian_matrix`.
        x: (..., V, C) dense.

    Returns:
        (..., V, C).
    """
    V = L.shape[0]
    if x.ndim < 2 or x.shape[-2] != V:
        raise LoosefitInputError(
            "apply_laplacian", "x", f"shape (..., {V}, C)", f"{tuple(x.shape)}"
        )
    L = L.to(device=x.device, dtype=x.dtype)
    batch, C = x.shape[:-2], x.shape[-1]
    flat = x.movedim(-2, 0).reshape(V, -1)  # (V, B*C), B the product of the batch dims
    out = torch.sparse.mm(L, flat)  # (V, B*C)
    return out.reshape(V, *batch, C).movedim(0, -2)  # (..., V, C)


class Laplacian(torch.nn.Module):
    """A fixed mesh Laplacian that follows its module's ``.to(device, dtype)``.

    ``Module.to`` does move sparse tensors, but sparse buffers are awkward
    elsewhere (``state_dict``, ``dtype`` casts, some devices). So the matrix is
    kept as two dense buffers, its COO ``indices`` (2, nnz) and ``values``
    (nnz,), which every ``.to()`` / ``.cuda()`` / ``.double()`` moves like any
    buffer; :attr:`matrix` rebuilds the (already coalesced) sparse tensor from
    them without copying. The buffers are not persistent: the operator is
    derived from the mesh, not learned.
    """

    indices: torch.Tensor
    values: torch.Tensor

    def __init__(
        self,
        faces: np.ndarray | torch.Tensor,
        num_vertices: int,
        kind: str = "uniform",
        vertices: np.ndarray | torch.Tensor | None = None,
    ) -> None:
        super().__init__()
        L = laplacian_matrix(faces, num_vertices, kind, vertices)
        self.num_vertices = num_vertices
        self.kind = kind
        self.register_buffer("indices", L.indices(), persistent=False)
        self.register_buffer("values", L.values(), persistent=False)

    @property
    def matrix(self) -> torch.Tensor:
        """(V, V) sparse COO matrix on the buffers' device and dtype."""
        V = self.num_vertices
        return torch.sparse_coo_tensor(
            self.indices, self.values, (V, V), is_coalesced=True, check_invariants=False
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(..., V, C) -> (..., V, C), see :func:`apply_laplacian`."""
        return apply_laplacian(self.matrix, x)
