"""Collision handling's fast path (``CollisionConfig.fast``) against the path before it:
the same garments within 0.5 mm, no more of them inside the body."""

from __future__ import annotations

import numpy as np
import pytest
import torch
import trimesh

import loosefit
from loosefit.geometry.query import Surface
from loosefit.inference.stages.collision import CollisionConfig, CollisionHandler
from tests.conftest import REPO, SALSA, needs_salsa
from tests.inference.stages.test_collision import _sheet
from tests.inference.stages.test_collision_finish import _two_spheres

TOLERANCE = 5e-4  # m: the fast path's garments against the path before it


def _sphere(radius: float = 0.3, subdivisions: int = 4) -> tuple[np.ndarray, np.ndarray]:
    s = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return np.asarray(s.vertices, np.float32), np.asarray(s.faces)


def _peanut() -> tuple[np.ndarray, np.ndarray]:
    """Two lobes and a waist between them (test_collision's crease)."""
    body = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    p = np.asarray(body.vertices)
    x = 0.35 * p[:, 0]
    radius = 0.2 * (1 - 0.55 * np.exp(-((x / 0.1) ** 2)))
    v = np.stack([x, radius * p[:, 1], radius * p[:, 2]], 1)
    return v.astype(np.float32), np.asarray(body.faces)


def _box() -> tuple[np.ndarray, np.ndarray]:
    b = trimesh.creation.box(extents=(0.3, 0.3, 0.3))
    return np.asarray(b.vertices, np.float32), np.asarray(b.faces)


def _overlap(radius: float, centre: list, subdivisions: int = 4):
    s = _two_spheres(radius, centre, subdivisions)
    return s.vertices, s.faces


def _hip_sheet():
    v, f = _sheet(30, 0.15, 0.0)
    v[:, 2] = np.sqrt(0.3015**2 - v[:, 0] ** 2 - v[:, 1] ** 2)  # 1.5 mm above the hip
    return v.astype(np.float32), f


# test_collision's synthetic cases: (body, garment, CollisionConfig fields)
CASES = {
    "sheet sunk into a sphere": (_sphere, lambda: _sheet(40, 0.4, 0.25), {}),
    "sheet through a box": (_box, lambda: _sheet(30, 0.3, 0.12), {}),
    "sheet in a crease": (_peanut, lambda: _sheet(40, 0.35, 0.12), {"iterations": 12}),
    "deep where body parts overlap": (
        lambda: _overlap(0.12, [0.3, 0, 0]),
        lambda: _sheet(40, 0.45, 0.1),
        {},
    ),
    "pinched between body parts": (
        lambda: _overlap(0.06, [0, 0, 0.32], 3),
        _hip_sheet,
        {"rest": True},
    ),
    "body through a face": (_sphere, lambda: _sheet(8, 0.4, 0.296), {"face_reach": 0.01}),
}


def _both(bv, bf, v, f, rest=False, **cfg):
    """Today's result and the fast path's, each on its own surface."""
    out = []
    for fast in (False, True):
        handler = CollisionHandler(
            f,
            len(v),
            CollisionConfig(reach=0.2, fast=fast, **cfg),
            rest=v.astype(np.float64) if rest else None,
        )
        surface = Surface(bv, bf, winding_number=not fast)
        out.append(handler.resolve(torch.from_numpy(np.asarray(v, np.float32)), surface))
    return out


def _inside(bv, bf, x: np.ndarray) -> int:
    """Vertices inside the body by warp's winding number at its default accuracy."""
    return int(Surface(bv, bf, winding_number=True).query(x, 1.0, sign="winding").inside.sum())


@pytest.mark.parametrize("case", list(CASES))
def test_the_fast_path_gives_todays_garment(case):
    body, garment, cfg = CASES[case]
    bv, bf = body()
    v, f = garment()
    today, fast = _both(bv, bf, v, f, **cfg)
    a, b = today.vertices.numpy(), fast.vertices.numpy()
    assert np.linalg.norm(a - b, axis=1).max() <= TOLERANCE
    assert _inside(bv, bf, b) <= _inside(bv, bf, a)
    assert fast.inside_after <= today.inside_after
    assert fast.moved > 0 or today.moved == 0


def test_the_banded_solve_is_superlus():
    v, f = _sheet(30, 0.3, 0.0)
    rng = np.random.default_rng(0)
    today = CollisionHandler(f, len(v), CollisionConfig(fast=False))
    fast = CollisionHandler(f, len(v), CollisionConfig(fast=True))
    active = np.zeros(len(v), bool)
    active[rng.choice(len(v), 12, replace=False)] = True
    region = today.dilate(active, 4)
    pinned = rng.normal(scale=0.01, size=(len(v), 3))
    expected = today._solve(pinned, active, region)
    np.testing.assert_allclose(fast._solve(pinned, active, region), expected, atol=1e-12)
    assert np.abs(expected[region & ~active]).max() > 1e-4  # the free vertices did move


def test_hints_change_no_answer():
    # a hint bounds the search by one face's distance: right, wrong, none or out of range,
    # the answers are the same as without
    bv, bf = _overlap(0.12, [0.3, 0, 0])
    surface = Surface(bv, bf)
    rng = np.random.default_rng(1)
    x = rng.uniform(-0.5, 0.5, size=(400, 3)).astype(np.float32)
    plain = surface.query(x, 0.1, sign="normal")
    hints = {
        "closest": plain.faces,
        "random": rng.integers(0, len(bf), len(x)),
        "none": np.full(len(x), -1),
        "out of range": np.full(len(x), len(bf) + 7),
    }
    assert (plain.faces >= 0).sum() > 50 and (plain.faces < 0).sum() > 50
    for sign in ("normal", "rays"):
        want = surface.query(x, 0.1, sign=sign)
        for name, hint in hints.items():
            got = surface.query(x, 0.1, sign=sign, hint=hint)
            np.testing.assert_array_equal(got.faces, want.faces, err_msg=f"{sign}, {name}")
            np.testing.assert_array_equal(got.points, want.points, err_msg=f"{sign}, {name}")
            np.testing.assert_array_equal(got.inside, want.inside, err_msg=f"{sign}, {name}")
    with pytest.raises(ValueError, match="hint"):
        surface.query(x, 0.1, sign="normal", hint=hints["none"][:3])


def test_rays_count_the_winding_number_where_body_parts_overlap():
    # inside the large sphere under the small one's skin: the closest face's side says
    # outside, the winding number and the rays say inside
    bv, bf = _overlap(0.12, [0.3, 0, 0])
    surface = Surface(bv, bf, winding_number=True)
    rng = np.random.default_rng(2)
    x = rng.uniform([-0.1, -0.3, -0.3], [0.5, 0.3, 0.3], size=(3000, 3)).astype(np.float32)
    winding = surface.query(x, 1.0, sign="winding")
    rays = surface.query(x, 1.0, sign="rays")
    normal = surface.query(x, 1.0, sign="normal")
    clear = winding.distance > 1e-4  # off the skin itself, where either answer is right
    np.testing.assert_array_equal(rays.inside[clear], winding.inside[clear])
    assert (rays.inside[clear] != normal.inside[clear]).sum() > 10  # the overlap was met
    np.testing.assert_allclose(rays.distance, normal.distance, atol=1e-6)  # ties: either face
    with pytest.raises(ValueError, match="sign"):
        surface.query(x, 1.0, sign="parity")
    # the rays alone, from the closest points a query gave: the same answers (the last
    # projection's first round reuses the solve's closest points so)
    near = surface.query(x, 0.05, sign="normal")  # some points beyond reach: face -1, outside
    assert (near.faces < 0).any()
    alone = surface.inside_by_rays(x, near.points, near.faces)
    np.testing.assert_array_equal(alone, surface.query(x, 0.05, sign="rays").inside)
    with pytest.raises(ValueError, match="closest"):
        surface.inside_by_rays(x, near.points[:10], near.faces)


@needs_salsa
def test_the_fast_path_over_a_real_rollout():
    from loosefit.inference.stages import Stages
    from loosefit.motion.motions import load_motion

    model = loosefit.load(REPO / "checkpoints" / "salsa" / "motion.pt").model
    motion = load_motion(
        SALSA / "60_01.bvh", model.avatar(), fps=model.fps, start_frame=10, max_frames=40
    )
    stages = Stages(overlap=False)
    assert model.collision.fast  # the default
    fast = model.animate(motion, stages=stages)
    with model.configured(CollisionConfig(fast=False)):
        today = model.animate(motion, stages=stages)
    gap = np.linalg.norm(fast.vertices - today.vertices, axis=-1)  # (T, V)
    # over the frames both inside tests agree on (within 0.05 mm of the skin they may not:
    # salsa 60_01 frame 31, one vertex 0.502 mm apart; docs/results/BENCHMARKS.md)
    assert np.quantile(gap, 0.9999) <= TOLERANCE and gap.max() <= 2 * TOLERANCE
    assert sum(c["inside_after"] for c in fast.collisions) <= sum(
        c["inside_after"] for c in today.collisions
    )
    assert sum(c["moved"] for c in fast.collisions) > 0


def test_first_hits_meet_the_skin_where_a_ray_does():
    # from a sphere's centre every ray meets its skin at the radius (a polyhedron: within
    # its sagitta); one that starts outside and points away meets nothing
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=0.3)
    surface = Surface(np.asarray(sphere.vertices, np.float32), np.asarray(sphere.faces))
    rng = np.random.default_rng(0)
    d = rng.normal(size=(50, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t, face = surface.first_hits(np.zeros((50, 3)), d, 1.0)
    assert (face >= 0).all() and np.allclose(t, 0.3, atol=2e-3)
    t, face = surface.first_hits(np.array([[0.0, 0.0, 0.5]]), np.array([[0.0, 0.0, 1.0]]), 1.0)
    assert face[0] == -1 and t[0] == 1.0
    # no farther than asked
    assert (surface.first_hits(np.zeros((1, 3)), d[:1], 0.2)[1] == -1).all()
    with pytest.raises(ValueError, match="directions"):
        surface.first_hits(np.zeros((2, 3)), np.zeros((3, 3)), 1.0)
