"""Collision handling (paper 3.5, Eq. 16): a garment pushed out of a body, its Laplacian kept."""

from __future__ import annotations

import numpy as np
import pytest
import torch
import trimesh

from loosefit.errors import LoosefitInputError
from loosefit.geometry.query import Surface
from loosefit.inference.stages.collision import (
    REALTIME,
    BodyCollider,
    CollisionConfig,
    CollisionHandler,
    collision_setting,
)
from tests.meshes import grid


def _sheet(n: int, half: float, z: float) -> tuple[np.ndarray, np.ndarray]:
    """An n x n grid over [-half, half]^2 at height z, and its triangles."""
    return grid(n, -half, half, z)


def _resolve(body: trimesh.Trimesh, garment: np.ndarray, faces: np.ndarray, **cfg):
    bv, bf = np.asarray(body.vertices, np.float32), np.asarray(body.faces)
    handler = CollisionHandler(faces, len(garment), CollisionConfig(reach=0.2, **cfg))
    return handler, handler.resolve(torch.from_numpy(garment), Surface(bv, bf))


def test_a_sheet_sunk_into_a_sphere_comes_out():
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=0.3)
    v, f = _sheet(40, 0.4, 0.25)  # the sphere's top is at 0.3: a cap 5 cm deep is inside
    inside = np.linalg.norm(v, axis=1) < 0.3
    assert inside.sum() > 100
    handler, r = _resolve(sphere, v, f)
    x = r.vertices.numpy()
    assert r.inside_before == inside.sum() and r.inside_after == 0
    # a smooth cap, not a step at the sphere's rim (Eq. 16's Laplacian term)
    assert r.laplacian_change < _naive_change(handler, v, r.vertices, inside)
    assert r.depth_before == pytest.approx(0.05 + 1e-3, abs=2e-3) and r.depth_after == 0.0
    # every vertex at least about eps outside (the sphere is a polyhedron: within 1 mm)
    assert np.linalg.norm(x, axis=1).min() > 0.3
    assert not np.isnan(x).any()
    # far from the sphere nothing moves
    far = np.linalg.norm(v[:, :2], axis=1) > 0.35
    np.testing.assert_array_equal(x[far], v[far])


def _naive_change(handler, v: np.ndarray, resolved: torch.Tensor, inside: np.ndarray) -> float:
    """The RMS Laplacian change had only the vertices that were inside moved, by as much."""
    d = resolved - torch.from_numpy(v)
    alone = torch.where(torch.from_numpy(inside)[:, None], d, torch.zeros_like(d))
    return float(handler.laplacian(alone).pow(2).sum(-1).mean().sqrt())


def inside_box(v: np.ndarray, half: float = 0.15) -> np.ndarray:
    return (np.abs(v) < half).all(1)


def test_a_sheet_through_a_box_comes_out_and_stays_smooth():
    box = trimesh.creation.box(extents=(0.3, 0.3, 0.3))  # z in [-0.15, 0.15]
    v, f = _sheet(30, 0.3, 0.12)  # 3 cm below the lid over the box's footprint
    handler, r = _resolve(box, v, f)
    x = r.vertices.numpy()
    # nearer the lid than any side wall (3 cm down): out through the lid; nearer a wall:
    # out through the wall (the closest point decides, as in Eq. 16)
    over = (np.abs(v[:, 0]) < 0.11) & (np.abs(v[:, 1]) < 0.11)
    assert r.inside_after == 0
    assert (x[over, 2] >= 0.15).all()
    # pushed to the lid (eps = 1 mm), not beyond (2.4 mm where the walls' pushes meet the
    # lid's: a face's point is not followed against its vertex's own way out)
    assert (x[over, 2] <= 0.15 + 3e-3).all()
    # the lid's edges force a crease, but a smaller one than where only the vertices that
    # were inside move, by as much
    assert r.laplacian_change < _naive_change(handler, v, r.vertices, inside_box(v))


def test_a_garment_outside_is_left_exactly_as_it_is():
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.3)
    v, f = _sheet(20, 0.4, 0.35)
    _, r = _resolve(sphere, v, f)
    assert torch.equal(r.vertices, torch.from_numpy(v))
    # one closest-point query, and the last projection's winding check of the near vertices
    assert r.moved == 0 and r.depth_before == 0.0 and r.iterations == 2


def test_a_vertex_deep_inside_is_pushed_out():
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=0.3)
    v, f = _sheet(20, 0.4, 0.35)
    k = np.argmin(np.linalg.norm(v[:, :2], axis=1))
    v[k, 2] = 0.2  # a spike 10 cm into the sphere
    _, r = _resolve(sphere, v, f)
    assert r.inside_before == 1 and r.inside_after == 0
    assert np.linalg.norm(r.vertices.numpy()[k]) > 0.3


def test_a_sheet_in_a_crease_of_the_body_comes_out():
    # a peanut: two lobes and a waist between them, like two thighs; the sheet dips into
    # the valley, where a vertex pushed out of one lobe along its normal can land in the
    # other and must be pushed on from there
    body = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    p = np.asarray(body.vertices)
    x = 0.35 * p[:, 0]
    radius = 0.2 * (1 - 0.55 * np.exp(-((x / 0.1) ** 2)))
    body = trimesh.Trimesh(np.stack([x, radius * p[:, 1], radius * p[:, 2]], 1), body.faces)
    v, f = _sheet(40, 0.35, 0.12)
    handler, r = _resolve(body, v, f, iterations=12)
    bv, bf = np.asarray(body.vertices, np.float32), np.asarray(body.faces)
    inside = Surface(bv, bf).query(r.vertices.numpy(), 1.0, sign="winding").inside
    assert r.inside_before > 100
    assert inside.sum() == 0 and r.inside_after == 0
    assert not np.isnan(r.vertices.numpy()).any()


def test_a_body_poking_through_a_face_between_outside_vertices_is_pushed_out():
    # a sheet of 11 cm cells over a sphere's top: every vertex is outside, but the middle
    # of the cell over the top is 4 mm inside (the body shows through the cloth)
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=0.3)
    v, f = _sheet(8, 0.4, 0.296)
    bv, bf = np.asarray(sphere.vertices, np.float32), np.asarray(sphere.faces)
    surface = Surface(bv, bf)
    assert not surface.query(v, 1.0, sign="winding").inside.any()
    a, b = np.meshgrid(np.linspace(0, 1, 9), np.linspace(0, 1, 9))
    keep = a + b <= 1
    bary = np.stack([a[keep], b[keep], 1 - a[keep] - b[keep]], 1)  # (K, 3)

    def face_points(x: np.ndarray) -> np.ndarray:
        return np.einsum("kc,fcd->fkd", bary, x[f]).reshape(-1, 3)

    assert surface.query(face_points(v), 1.0, sign="winding").inside.any()
    # cells this coarse need the faces checked farther out than the default 5 mm (for
    # the 2 cm edges of the skirt, a body bump between vertices 5 mm out is rare)
    _, r = _resolve(sphere, v, f, face_reach=0.01)
    assert not surface.query(face_points(r.vertices.numpy()), 1.0, sign="winding").inside.any()


def test_body_collider_poses_lazily_and_resolves_each_frame():
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.3)
    bv, bf = np.asarray(sphere.vertices, np.float32), np.asarray(sphere.faces)
    calls = []

    def pose(start, stop):  # the sphere rising 1 cm a frame
        calls.append((start, stop))
        return np.stack([bv + [0, 0, 0.01 * t] for t in range(start, stop)])

    v, f = _sheet(20, 0.4, 0.32)
    collide = BodyCollider(
        CollisionHandler(f, len(v), CollisionConfig(reach=0.2)), bf, pose, num_frames=6, chunk=4
    )
    results = [collide(t, torch.from_numpy(v)) for t in range(6)]
    assert calls == [(0, 4), (4, 6)]
    assert results[0].inside_before == 0 and results[5].inside_before > 0
    assert all(r.inside_after == 0 for r in results)


def test_config_and_shape_checks():
    with pytest.raises(LoosefitInputError, match="epsilon"):
        CollisionConfig(epsilon=0.0)
    with pytest.raises(LoosefitInputError, match="rings"):
        CollisionConfig(rings=0)
    with pytest.raises(LoosefitInputError, match="stretch"):
        CollisionConfig(stretch=1.0)
    with pytest.raises(LoosefitInputError, match="relax"):
        CollisionConfig(relax=-1)
    v, f = _sheet(5, 0.1, 0.0)
    with pytest.raises(LoosefitInputError, match="rest"):
        CollisionHandler(f, len(v), rest=v[:-1])
    h = CollisionHandler(f, len(v))
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.3)
    bv, bf = np.asarray(sphere.vertices, np.float32), np.asarray(sphere.faces)
    with pytest.raises(LoosefitInputError, match="garment"):
        h.resolve(torch.zeros(len(v) + 1, 3), Surface(bv, bf))


def test_push_out_moves_each_close_vertex_along_the_normal_to_epsilon():
    from loosefit.inference.stages.push_out import PushOutHandler

    sphere = trimesh.creation.icosphere(subdivisions=4, radius=0.3)
    v, f = _sheet(30, 0.4, 0.28)
    handler = PushOutHandler(f, len(v), epsilon=0.002, reach=0.2)
    r = handler.resolve(
        torch.from_numpy(v),
        Surface(np.asarray(sphere.vertices, np.float32), np.asarray(sphere.faces)),
    )
    x = r.vertices.numpy()
    inside = np.linalg.norm(v, axis=1) < 0.3
    assert r.inside_before == inside.sum() > 0 and r.inside_after == 0
    # along the normal: the pushed vertices stay on their rays from the centre
    moved = np.linalg.norm(x - v, axis=1) > 1e-7
    dirs = x[moved] / np.linalg.norm(x[moved], axis=1, keepdims=True)
    np.testing.assert_allclose(
        dirs, v[moved] / np.linalg.norm(v[moved], axis=1, keepdims=True), atol=2e-3
    )
    assert np.abs(np.linalg.norm(x[inside], axis=1) - 0.302).max() < 2e-3  # the faceted sphere
    # vertices farther than epsilon are untouched
    far = np.linalg.norm(v, axis=1) > 0.31
    np.testing.assert_array_equal(x[far], v[far])
    with pytest.raises(LoosefitInputError, match="garment"):
        handler.resolve(
            torch.zeros(3, 3),
            Surface(np.asarray(sphere.vertices, np.float32), np.asarray(sphere.faces)),
        )


def test_collision_settings_full_and_realtime():
    config = CollisionConfig(epsilon=2e-3)
    assert collision_setting(config, "full") is config
    quick = collision_setting(config, "realtime")
    assert quick.epsilon == 2e-3 and all(getattr(quick, k) == v for k, v in REALTIME.items())
    with pytest.raises(LoosefitInputError, match="full or realtime"):
        collision_setting(config, "fast")
