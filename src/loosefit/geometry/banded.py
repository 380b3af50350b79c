"""A sparse symmetric positive definite system factorised once, solved for many right-hand sides.

Projective dynamics (:class:`~loosefit.inference.stages.lengths.LengthRestorer`) solves one fixed
system ``A`` of a garment's free vertices a few times per frame, for every coordinate of
every frame at once: ``A X = R`` with ``R`` (n, K), K = 3 x frames. A garment's mesh in
reverse Cuthill-McKee order is banded (the skirt's 2,268 free vertices: a bandwidth of
81), and a banded matrix's Cholesky factor fills in only inside its envelope. So:

1. :func:`band_order` gives the order and the bandwidth it reaches; the caller takes its
   unknowns in that order (or decides the band is too wide and solves another way);
2. :class:`BlockBandedCholesky` factorises ``A = L L^T`` once
   (:func:`scipy.linalg.cholesky_banded`) and cuts ``L`` into diagonal blocks so that
   each block's rows reach back only into the block before it (the envelope's levels,
   much like the levels of the breadth-first search behind the order). ``L`` is then
   block-bidiagonal, and each block of the forward and the backward sweep is one small
   dense matrix product over all K columns::

       y_j = L_jj^-1 r_j - (L_jj^-1 L_j,j-1) y_j-1
       x_j = L_jj^-T y_j - (L_j+1,j L_jj^-1)^T x_j+1

LAPACK's banded solve (``pbtrs``, what :func:`scipy.linalg.cho_solve_banded` calls) takes
the right-hand sides one at a time, a matrix-vector sweep each: for the skirt with
K = 192 it is slower (22 ms a solve on one core) than the dense inverse it would replace
(16 ms, one float32 matrix product). The blocks turn the same factor into matrix-matrix
products (2 ms in float32).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sl
import scipy.sparse as sp
from scipy.sparse.csgraph import reverse_cuthill_mckee

# blocks smaller than this are merged with the next (a block costs a Python step and a
# small matrix product; merging keeps the factor block-bidiagonal)
MIN_BLOCK = 24


def band_order(matrix: sp.spmatrix) -> tuple[np.ndarray, int]:
    """The reverse Cuthill-McKee order of a symmetric (n, n) matrix: (n,) the unknowns in
    order, and the bandwidth ``max |i - j|`` over its entries in that order."""
    a = sp.csr_matrix(matrix)
    order = reverse_cuthill_mckee(a, symmetric_mode=True)
    rank = np.empty(len(order), np.int64)  # (n,) each unknown's place in the order
    rank[order] = np.arange(len(order))
    c = a.tocoo()
    width = int(np.abs(rank[c.row] - rank[c.col]).max()) if c.nnz else 0
    return order.astype(np.int64), width


class BlockBandedCholesky:
    """``A^-1 R`` for a banded symmetric positive definite ``A``, factorised once.

    Args:
        matrix: (n, n) sparse, symmetric positive definite, already in a band-reducing
            order (:func:`band_order`): the solve's cost goes with its envelope.
        dtype: of the stored blocks and the solve. float32 halves the time; its error
            stays near float32's resolution of the result as long as ``A`` is well
            conditioned (the factor is taken in float64 either way).
    """

    def __init__(self, matrix: sp.spmatrix, dtype=np.float32) -> None:
        a = sp.csr_matrix(matrix)
        a.sort_indices()
        n = a.shape[0]
        self.n, self.dtype = n, np.dtype(dtype)
        # each row's first column at or below the diagonal (the envelope), then its lower
        # bound over the rows after it: the fill of L stays inside the envelope
        first = np.minimum.reduceat(a.indices, a.indptr[:-1]) if n else np.zeros(0, np.int64)
        reach = np.minimum.accumulate(first[::-1])[::-1]  # (n,) non-decreasing
        self.bandwidth = width = int((np.arange(n) - first).max()) if n else 0
        lower = sp.tril(a).tocoo()
        band = np.zeros((width + 1, n))  # lower banded storage: band[i - j, j] = A[i, j]
        band[lower.row - lower.col, lower.col] = lower.data
        factor = sl.cholesky_banded(band, lower=True, check_finite=False)  # (b + 1, n)
        self.starts = starts = _levels(reach, n)  # (nb + 1,) block j is starts[j]:starts[j + 1]
        # (m_j, m_j-1 + m_j) forward and (m_j, m_j + m_j+1) backward: [-L_jj^-1 L_j,j-1, L_jj^-1]
        # and [L_jj^-T, -(L_j+1,j L_jj^-1)^T], so that a block's step is one product
        self._forward, self._backward = [], []
        inverse = [None] * (len(starts) - 1)
        for j in range(len(starts) - 1):
            s, e = starts[j], starts[j + 1]
            inverse[j] = sl.solve_triangular(_block(factor, s, e, s, e), np.eye(e - s), lower=True)
        for j in range(len(starts) - 1):
            s, e = starts[j], starts[j + 1]
            p = starts[j - 1] if j else s
            below = -inverse[j] @ _block(factor, s, e, p, s)  # (m_j, m_j-1)
            self._forward.append(np.ascontiguousarray(np.hstack([below, inverse[j]]), dtype))
            q = starts[j + 2] if j + 2 < len(starts) else e
            above = -(_block(factor, e, q, s, e) @ inverse[j]).T  # (m_j, m_j+1)
            self._backward.append(np.ascontiguousarray(np.hstack([inverse[j].T, above]), dtype))

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """(n, K) -> (n, K) ``A^-1 rhs`` in the solver's dtype (a new array)."""
        if rhs.shape[0] != self.n:
            raise ValueError(f"right-hand sides of {rhs.shape[0]} rows for a system of {self.n}")
        work = np.array(rhs, self.dtype, order="C")  # (n, K): r, then y, then x in place
        starts = self.starts
        nb = len(starts) - 1
        for j in range(nb):  # forward: L y = r; rows p:s hold y_j-1, s:e still r_j
            s, e = starts[j], starts[j + 1]
            p = starts[j - 1] if j else s
            work[s:e] = self._forward[j] @ work[p:e]
        for j in range(nb - 1, -1, -1):  # backward: L^T x = y; rows e:q hold x_j+1
            s, e = starts[j], starts[j + 1]
            q = starts[j + 2] if j + 2 <= nb else e
            work[s:e] = self._backward[j] @ work[s:q]
        return work


def _levels(reach: np.ndarray, n: int) -> np.ndarray:
    """(nb + 1,) block starts such that every row of block j + 1 has ``reach >= `` the start
    of block j: block j + 2 begins at the first row that reaches no further back than
    block j + 1 (``reach`` non-decreasing). Blocks under :data:`MIN_BLOCK` rows are merged
    with the next one, which keeps that property."""
    if n == 0:
        return np.zeros(1, np.int64)
    starts = [0, max(1, int(np.searchsorted(reach, 1)))]
    while starts[-1] < n:
        starts.append(max(starts[-1] + 1, int(np.searchsorted(reach, starts[-1]))))
    starts[-1] = n
    merged = [0]
    for s in starts[1:-1]:
        if s - merged[-1] >= MIN_BLOCK:
            merged.append(s)
    if len(merged) > 1 and n - merged[-1] < MIN_BLOCK:
        merged.pop()  # the last block too small: its rows join the one before
    merged.append(n)
    out = np.array(merged, np.int64)
    # every row of block j reaches back no further than block j - 1 (so L is block-bidiagonal)
    assert all(reach[out[j]] >= out[j - 1] for j in range(1, len(out) - 1))
    return out


def _block(band: np.ndarray, r0: int, r1: int, c0: int, c1: int) -> np.ndarray:
    """Rows r0:r1, columns c0:c1 of the lower triangular matrix held in ``band`` (b + 1, n)
    (``band[i - j, j]``), dense (r1 - r0, c1 - c0)."""
    i, j = np.meshgrid(np.arange(r0, r1), np.arange(c0, c1), indexing="ij")
    k = i - j
    inside = (k >= 0) & (k < band.shape[0])
    out = np.zeros((r1 - r0, c1 - c0))
    out[inside] = band[k[inside], j[inside]]
    return out
