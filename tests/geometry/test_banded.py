"""The block-banded Cholesky solve against a dense solve of the same system."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from loosefit.geometry.banded import MIN_BLOCK, BlockBandedCholesky, band_order


def grid_system(n: int, seed: int = 0) -> sp.csr_matrix:
    """(n^2, n^2) ``L^T L + 0.01 I`` of an n x n grid's graph Laplacian, its vertices
    shuffled (so that the band comes from band_order, not from the numbering)."""
    i = np.arange(n * n).reshape(n, n)
    e = np.r_[np.c_[i[:, :-1].ravel(), i[:, 1:].ravel()], np.c_[i[:-1].ravel(), i[1:].ravel()]]
    perm = np.random.default_rng(seed).permutation(n * n)
    e = perm[e]
    m = len(e)
    rows = np.r_[np.arange(m), np.arange(m)]
    inc = sp.csr_matrix((np.r_[np.ones(m), -np.ones(m)], (rows, e.T.ravel())), shape=(m, n * n))
    return (inc.T @ inc + 0.01 * sp.identity(n * n)).tocsr()


def test_band_order_of_a_shuffled_path():
    # a path's graph in any numbering: reverse Cuthill-McKee walks it, bandwidth 1
    perm = np.random.default_rng(1).permutation(30)
    a = sp.diags([np.ones(29), 2 * np.ones(30), np.ones(29)], [-1, 0, 1]).tocsr()
    shuffled = a[perm][:, perm]
    order, width = band_order(shuffled)
    assert width == 1 and sorted(order.tolist()) == list(range(30))
    c = shuffled[order][:, order].tocoo()
    assert np.abs(c.row - c.col).max() == 1


@pytest.mark.parametrize("n", [3, 7, 20])  # one block, a few, many
def test_solve_matches_a_dense_solve(n):
    a = grid_system(n)
    order, width = band_order(a)
    a = a[order][:, order]
    rhs = np.random.default_rng(2).standard_normal((n * n, 12))
    want = np.linalg.solve(a.toarray(), rhs)
    exact = BlockBandedCholesky(a, np.float64)
    assert exact.bandwidth == width
    assert exact.starts[0] == 0 and exact.starts[-1] == n * n
    if n == 20:  # 400 unknowns, bandwidth ~20: several blocks, each at least MIN_BLOCK
        assert len(exact.starts) > 3 and np.diff(exact.starts).min() >= MIN_BLOCK
    np.testing.assert_allclose(exact.solve(rhs), want, rtol=0, atol=1e-10 * np.abs(want).max())
    single = BlockBandedCholesky(a, np.float32).solve(rhs)
    assert single.dtype == np.float32
    np.testing.assert_allclose(single, want, rtol=0, atol=1e-5 * np.abs(want).max())


def test_uncoupled_unknowns():
    # a diagonal system (bandwidth 0): every row its own level, merged into blocks
    d = np.linspace(1.0, 3.0, 100)
    s = BlockBandedCholesky(sp.diags(d), np.float64)
    rhs = np.arange(200.0).reshape(100, 2)
    assert s.bandwidth == 0
    np.testing.assert_allclose(s.solve(rhs), rhs / d[:, None], rtol=1e-14)
    with pytest.raises(ValueError, match="99 rows"):
        s.solve(rhs[:99])
