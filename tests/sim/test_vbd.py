"""The solver's initial guess (loosefit.sim.vbd): Newton's inertial prediction, or the VBD
paper's adaptive one, on single particles and on a tiny skirt."""

from __future__ import annotations

import newton
import numpy as np
import pytest
import warp as wp

from loosefit.errors import LoosefitInputError
from loosefit.garment.skirt import SkirtConfig
from loosefit.sim.cloth_config import ClothConfig
from loosefit.sim.vbd import adaptive_forward_step_kernel, chebyshev_omegas, solver_class

TINY_SKIRT = SkirtConfig(style="aline", rings=8, segments=24)


ACTIVE = int(newton.ParticleFlags.ACTIVE)  # the flag bit of a simulated particle


def _forward(vel_before, vel, active=(1, 1, 1, 1), dt=0.01, g=(0.0, 0.0, -10.0)):
    n = len(vel)
    arr = lambda x, t=wp.vec3: wp.array(np.asarray(x, np.float32), dtype=t)  # noqa: E731
    pos = arr(np.arange(3 * n).reshape(n, 3))
    before = arr(vel_before)
    outs = [wp.zeros(n, dtype=wp.vec3) for _ in range(3)]
    wp.launch(
        adaptive_forward_step_kernel,
        dim=n,
        inputs=[
            dt,
            arr([g]),
            wp.zeros(n, dtype=wp.int32),
            pos,
            arr(vel),
            before,
            wp.ones(n, dtype=float),
            wp.zeros(n, dtype=wp.vec3),
            # Newton's flags: the active bit where ``active``, another bit everywhere
            wp.array(np.asarray(active, np.int32) * ACTIVE | 2 * ACTIVE, dtype=wp.int32),
            ACTIVE,
        ],
        outputs=outs,
    )
    prev, inertia, disp = (o.numpy() for o in outs)
    return pos.numpy(), before.numpy(), prev, inertia, disp


def test_the_guess_follows_the_last_acceleration_along_gravity_clamped():
    dt = 0.01
    vel = np.array([[1.0, 0, 0], [0, 0, -0.1], [0, 0, -0.5], [0, 0, 0.2]])
    # accelerations (vel - before) / dt: none; g; beyond g (clamped to g); upwards (none),
    # with a sideways part that gravity's direction leaves out
    before = vel - dt * np.array([[0, 0, 0], [0, 0, -10.0], [0, 0, -30.0], [5.0, 0, 4.0]])
    pos, kept, prev, inertia, disp = _forward(before, vel, dt=dt)
    np.testing.assert_allclose(prev, pos)
    np.testing.assert_allclose(kept, vel, atol=1e-7)  # the next substep's "before"
    # the target is Newton's own: x + (v + g dt) dt
    np.testing.assert_allclose(inertia, pos + (vel + dt * np.array([0, 0, -10.0])) * dt, atol=1e-6)
    gdt2 = np.array([0, 0, -10.0]) * dt * dt
    want = vel * dt + np.array([0.0, 1.0, 1.0, 0.0])[:, None] * gdt2
    np.testing.assert_allclose(disp, want, atol=1e-7)


def test_a_pinned_particle_stays_where_it_is():
    pos, _, _, inertia, disp = _forward(np.zeros((2, 3)), np.ones((2, 3)), active=(0, 1))
    np.testing.assert_allclose(inertia[0], pos[0])
    np.testing.assert_allclose(disp[0], 0.0)
    assert np.abs(disp[1]).sum() > 0


def test_the_guess_is_named_or_refused():
    assert solver_class("inertia") is newton.solvers.SolverVBD
    assert issubclass(solver_class("adaptive"), newton.solvers.SolverVBD)
    with pytest.raises(ValueError, match="initial_guess"):
        solver_class("zero")
    with pytest.raises(LoosefitInputError, match="initial_guess"):
        ClothConfig(initial_guess="zero")


def test_chebyshevs_weights():
    rho = 0.9
    w = chebyshev_omegas(rho, 5)
    assert w[0] == 1.0 and w[1] == pytest.approx(2 / (2 - rho**2))
    for a, b in zip(w[1:], w[2:], strict=False):
        assert b == pytest.approx(4 / (4 - rho**2 * a))
    assert all(1.0 < x < 2.0 for x in w[1:])
    assert chebyshev_omegas(0.0, 4) == [1.0, 1.0, 1.0, 1.0]
    with pytest.raises(ValueError, match="chebyshev_rho"):
        solver_class("inertia", 1.0)
    with pytest.raises(LoosefitInputError, match="chebyshev_rho"):
        ClothConfig(chebyshev_rho=-0.1)


def test_accelerated_sweeps_stretch_the_hanging_skirt_less_and_keep_it_out(avatar):
    """The same sweeps, accelerated: the drape nearer its rest lengths (the iterations
    converge further), finite, its waistband on the body and no vertex in the body."""
    from loosefit.fitting.place import fit_skirt
    from loosefit.garment.quality import edge_strain
    from loosefit.geometry.query import closest_points
    from loosefit.sim.driver import settle

    skirt = fit_skirt(avatar, TINY_SKIRT)
    plain = settle(avatar, skirt, ClothConfig.tiny())
    fast = settle(avatar, skirt, ClothConfig.tiny(chebyshev_rho=0.9))
    assert np.isfinite(fast).all()
    strain = [np.median(edge_strain(g[None], skirt)[0]) for g in (plain, fast)]
    assert strain[1] < 0.8 * strain[0]
    J = len(avatar.joint_names)
    import torch

    rest = (
        avatar.pose(torch.eye(3).expand(1, J, 3, 3).contiguous(), torch.zeros(1, 3))
        .vertices[0]
        .numpy()
    )
    hit = closest_points(rest, avatar.collider_faces(arms=False).numpy(), fast)
    assert hit.distance[skirt.waist].max() < 0.01
    assert not hit.inside.any()
