import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.geometry.cap import boundary_loops, cut_and_cap, triangle_keys


def _edges_used_twice(faces: np.ndarray) -> bool:
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    # Closed and consistently oriented: every directed edge once, and its reverse once.
    pairs = {tuple(e) for e in directed.tolist()}
    return len(pairs) == len(directed) and all((b, a) in pairs for a, b in pairs)


def _volume(v: np.ndarray, f: np.ndarray) -> float:
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def _grid_cylinder(rings: int = 6, sides: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """A closed tube (capped with a centre vertex at each end), outward-facing."""
    ang = 2 * np.pi * np.arange(sides) / sides
    ring = np.stack([np.cos(ang), np.sin(ang)], 1)
    v = [np.c_[ring, np.full(sides, z)] for z in np.linspace(0, 1, rings)]
    v = np.concatenate(v + [np.array([[0, 0, 0.0], [0, 0, 1.0]])])
    f = []
    for r in range(rings - 1):
        for s in range(sides):
            a, b = r * sides + s, r * sides + (s + 1) % sides
            f += [(a, b, b + sides), (a, b + sides, a + sides)]
    bottom, top = rings * sides, rings * sides + 1
    for s in range(sides):
        f.append((bottom, (s + 1) % sides, s))
        t0 = (rings - 1) * sides
        f.append((top, t0 + s, t0 + (s + 1) % sides))
    return v, np.asarray(f)


def test_cut_and_cap_closes_the_hole_and_keeps_orientation():
    v, f = _grid_cylinder()
    assert _edges_used_twice(f) and _volume(v, f) > 0
    removed = v[:, 2] > 0.7  # the top two rings and the top centre
    capped = cut_and_cap(f, removed)
    assert _edges_used_twice(capped)
    assert boundary_loops(capped) == []
    # A face goes only when all its corners go: the hole is the ring at z = 0.8, and the
    # flat cap there leaves exactly the volume of the shorter tube.
    assert _volume(v, capped) == pytest.approx(0.8 * _volume(v, f))
    # Only the mesh's own vertices are used.
    assert capped.max() < len(v)


def test_boundary_loops_follow_the_faces_edges():
    v, f = _grid_cylinder(rings=3, sides=5)
    open_tube = f[~(v[f][:, :, 2] > 0.9).all(1)]  # the top cap goes, its ring stays
    loops = boundary_loops(open_tube)
    assert len(loops) == 1 and sorted(loops[0].tolist()) == list(range(10, 15))
    directed = {
        tuple(e)
        for e in np.concatenate(
            [open_tube[:, [0, 1]], open_tube[:, [1, 2]], open_tube[:, [2, 0]]]
        ).tolist()
    }
    loop = loops[0].tolist()
    assert all((loop[i], loop[(i + 1) % len(loop)]) in directed for i in range(len(loop)))


def test_a_pinched_boundary_is_an_error():
    # Two triangles that meet at one vertex only: vertex 0 starts two boundary edges.
    f = np.array([[0, 1, 2], [0, 3, 4]])
    with pytest.raises(LoosefitInputError, match="pinch at vertex 0"):
        boundary_loops(f)


def test_a_non_manifold_edge_is_an_error():
    f = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    with pytest.raises(LoosefitInputError, match="manifold"):
        boundary_loops(f)


def test_triangle_keys_match_the_same_vertices_in_any_order():
    a = np.array([[0, 1, 2], [2, 3, 4], [5, 6, 7]])
    b = np.array([[4, 2, 3], [1, 2, 0], [0, 1, 3]])
    ka, kb = triangle_keys(a, b)
    assert ka.dtype == np.int64 and ka.shape == (3,) and kb.shape == (3,)
    assert kb[0] == ka[1] and kb[1] == ka[0]  # rotated and reflected orders
    assert kb[2] not in ka and len(set(ka)) == 3
