"""The pure mesh checks on meshes small enough to know every answer: a grid, a cube, a
tetrahedron's fin, a quad split into two UV charts."""

from __future__ import annotations

import numpy as np

from loosefit.garment.mesh_checks import (
    boundary_loops,
    degenerate_faces,
    hem_loop,
    nonmanifold_edges,
    triangle_areas,
    uv_charts,
    uv_triangle_areas,
)
from tests.meshes import cube, grid


def test_areas_of_a_grid_and_a_cube_add_up():
    v, f = grid(5, 0.0, 2.0)  # a 2 m square in 32 triangles
    a = triangle_areas(v, f)
    assert a.dtype == np.float64 and a.shape == (32,)
    np.testing.assert_allclose(a, 4.0 / 32, rtol=1e-12)
    v, f = cube(2.0)
    np.testing.assert_allclose(triangle_areas(v, f).sum(), 24.0, rtol=1e-12)


def test_repeated_and_collinear_corners_are_degenerate():
    v = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0]], np.float32)
    f = np.array([[0, 1, 3], [0, 1, 2], [1, 1, 3], [0, 3, 1]])  # ok, collinear, repeated, ok
    np.testing.assert_array_equal(degenerate_faces(v, f), [1, 2])
    assert degenerate_faces(v, np.zeros((0, 3), int)).shape == (0,)


def test_an_edge_of_three_faces_is_non_manifold():
    fin = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])  # three faces on edge (0, 1)
    np.testing.assert_array_equal(nonmanifold_edges(fin), [[0, 1]])
    assert nonmanifold_edges(cube()[1]).shape == (0, 2)


def test_a_grid_has_one_boundary_loop_with_the_surface_on_its_left():
    v, f = grid(3, 0.0, 1.0)
    (loop,) = boundary_loops(f)
    assert sorted(loop.tolist()) == [0, 1, 2, 3, 5, 6, 7, 8]  # every vertex but the centre
    # with the surface on its left the loop turns as the faces do: its signed area (the
    # shoelace) is the faces' signed areas added up, the unit square with their sign
    x, y = v[loop, 0].astype(float), v[loop, 1].astype(float)
    shoelace = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
    e1, e2 = v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]
    faces = 0.5 * np.sum(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    assert abs(abs(faces) - 1.0) < 1e-6 and abs(shoelace - faces) < 1e-6
    assert boundary_loops(cube()[1]) == []  # closed


def test_the_hem_is_the_lower_opening_of_a_tube():
    n = 8
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = np.stack([np.cos(a), np.sin(a)], 1)
    v = np.concatenate([np.c_[ring, np.full(n, 1.0)], np.c_[ring, np.zeros(n)]]).astype(np.float32)
    i = np.arange(n)
    j = (i + 1) % n
    f = np.concatenate([np.stack([i, i + n, j], 1), np.stack([j, i + n, j + n], 1)])
    assert len(boundary_loops(f)) == 2
    assert sorted(hem_loop(v, f).tolist()) == list(range(n, 2 * n))  # the ring at z = 0
    assert hem_loop(*cube()).shape == (0,)


def test_uv_areas_are_signed_and_charts_are_the_connected_pieces():
    uvs = np.array([[0, 0], [1, 0], [0, 1], [0.5, 0.5], [0.9, 0.5], [0.5, 0.9]], np.float32)
    face_uvs = np.array([[0, 1, 2], [3, 5, 4]])  # counter-clockwise, then clockwise
    np.testing.assert_allclose(uv_triangle_areas(uvs, face_uvs), [0.5, -0.08], rtol=1e-6)
    labels = uv_charts(face_uvs, 7)  # the seventh coordinate is used by no face
    assert labels.dtype == np.int64
    assert len(set(labels[:3])) == 1 and len(set(labels[3:6])) == 1
    assert len({labels[0], labels[3], labels[6]}) == 3
