import numpy as np

from loosefit.geometry.edges import unique_edges
from tests.meshes import cube, grid


def _naive_edges(faces):
    """Each face's three sides as sorted pairs, counted in a plain dict."""
    count = {}
    for f in faces:
        for a, b in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0])):
            key = (min(a, b), max(a, b))
            count[key] = count.get(key, 0) + 1
    keys = sorted(count)
    return np.array(keys, np.int64).reshape(-1, 2), np.array([count[k] for k in keys], np.int64)


def test_two_triangles_share_their_diagonal():
    edges, counts = unique_edges(np.array([[0, 1, 2], [2, 1, 3]]))
    assert edges.tolist() == [[0, 1], [0, 2], [1, 2], [1, 3], [2, 3]]
    assert counts.tolist() == [1, 1, 2, 1, 1]
    assert edges.dtype == np.int64 and counts.dtype == np.int64


def test_edges_match_a_plain_loop_on_a_grid():
    _, f = grid(5, 0.0, 1.0)
    edges, counts = unique_edges(f)
    want_edges, want_counts = _naive_edges(f.tolist())
    np.testing.assert_array_equal(edges, want_edges)
    np.testing.assert_array_equal(counts, want_counts)
    # a 5 x 5 grid: 2 * 5 * 4 axis edges and 16 diagonals; the border's 16 edges used once
    assert len(edges) == 56 and (counts == 1).sum() == 16


def test_every_edge_of_a_closed_cube_is_used_twice():
    _, f = cube()
    edges, counts = unique_edges(f)
    assert len(edges) == 18  # 12 sides of the cube and 6 diagonals
    assert (counts == 2).all()
    assert (edges[:, 0] < edges[:, 1]).all()


def test_no_faces_no_edges():
    edges, counts = unique_edges(np.zeros((0, 3), np.int64))
    assert edges.shape == (0, 2) and counts.shape == (0,)
