"""Newton's VBD cloth solver, and variants that converge further in as many iterations.

VBD (He Chen et al. 2024) minimises, each substep, the inertia-plus-elasticity energy by a
few Gauss-Seidel iterations (one colour of vertices at a time) from an initial guess. With
few iterations it stops short, and where it stops depends on where it started. Newton has
no option for either lever of the paper's; this module subclasses its ``SolverVBD`` and
overrides two of its methods (``_initialize_particles``, ``_solve_particle_iteration``):

* **Chebyshev's acceleration** (``ClothConfig.chebyshev_rho``; the paper's section 3.7).
  Each iteration after the first overshoots along the last two: ``d = w (d^ - d'') + d''``
  on the displacements, with Chebyshev's weights ``w`` for a spectral radius ``rho``. The
  overshoot is truncated again as Newton truncates every iteration (the displacement bounds
  of its divide-and-truncate contact), so the cloth still never crosses itself or the body.
* **The adaptive initial guess** (``ClothConfig.initial_guess = "adaptive"``; the paper's
  section 3.6). Newton starts at the inertial prediction ``x + v dt + g dt^2``: every vertex
  falls freely for a substep. The adaptive guess starts at ``x + v dt + a~ dt^2``, ``a~`` the
  last substep's acceleration along gravity clamped to ``[0, |g|]``, so a hanging vertex
  starts where it is. What the iterations minimise (the inertial target) is Newton's own.
  On a flared skirt it leaves the cloth floating (docs/results/SIM_SPEED.md): measured, not
  recommended.

:func:`solver_class` gives Newton's own solver when neither is asked for.
"""

from __future__ import annotations

from loosefit.warp_log import import_warp

wp = import_warp()  # its banner and kernel loads on standard error


@wp.kernel
def adaptive_forward_step_kernel(
    dt: float,
    gravity: wp.array(dtype=wp.vec3),
    particle_world: wp.array(dtype=wp.int32),
    pos: wp.array(dtype=wp.vec3),
    vel: wp.array(dtype=wp.vec3),
    vel_before: wp.array(dtype=wp.vec3),
    inv_mass: wp.array(dtype=float),
    external_force: wp.array(dtype=wp.vec3),
    flags: wp.array(dtype=wp.int32),
    active_bit: int,
    pos_prev: wp.array(dtype=wp.vec3),
    inertia_out: wp.array(dtype=wp.vec3),
    displacements_out: wp.array(dtype=wp.vec3),
):
    """Newton's ``forward_step`` (the inertial target, the step's start kept in ``pos_prev``)
    with the adaptive initial guess: the displacement ``v dt + a~ dt^2``, ``a~`` the last
    substep's acceleration ``(vel - vel_before) / dt`` along gravity, clamped to
    ``[0, |g|]``; ``vel_before`` becomes ``vel``. A particle without ``active_bit`` in its
    ``flags`` stays where it is. One thread a particle."""
    i = wp.tid()
    x = pos[i]
    v = vel[i]
    a = (v - vel_before[i]) / dt
    vel_before[i] = v
    pos_prev[i] = x
    if (flags[i] & active_bit) == 0 or inv_mass[i] == 0.0:
        inertia_out[i] = x
        displacements_out[i] = wp.vec3(0.0, 0.0, 0.0)
        return
    g = gravity[particle_world[i]]
    v_new = v + (g + external_force[i] * inv_mass[i]) * dt
    inertia_out[i] = x + v_new * dt
    g_norm = wp.length(g)
    along = wp.vec3(0.0, 0.0, 0.0)
    if g_norm > 0.0:
        g_dir = g / g_norm
        along = wp.clamp(wp.dot(a, g_dir), 0.0, g_norm) * g_dir
    displacements_out[i] = v * dt + along * (dt * dt)


@wp.kernel
def chebyshev_kernel(
    omega: float,
    displacement: wp.array(dtype=wp.vec3),
    last: wp.array(dtype=wp.vec3),
    before_last: wp.array(dtype=wp.vec3),
):
    """Chebyshev's semi-iterative step on the sweeps' displacements: ``d = omega (d - d'')
    + d''`` with ``d''`` the displacement two sweeps back, which becomes ``last`` (the caller
    stores the new one in ``last`` once it is truncated)."""
    i = wp.tid()
    displacement[i] = omega * (displacement[i] - before_last[i]) + before_last[i]
    before_last[i] = last[i]


def chebyshev_omegas(rho: float, iterations: int) -> list[float]:
    """Chebyshev's weights of the sweeps ``1 .. iterations`` for a spectral radius ``rho``:
    1, ``2 / (2 - rho^2)``, then ``4 / (4 - rho^2 w)`` of the last (all 1 for ``rho`` 0)."""
    omegas: list[float] = []
    for n in range(iterations):
        if n == 0:
            omegas.append(1.0)
        elif n == 1:
            omegas.append(2.0 / (2.0 - rho * rho))
        else:
            omegas.append(4.0 / (4.0 - rho * rho * omegas[-1]))
    return omegas


def solver_class(initial_guess: str = "inertia", chebyshev_rho: float = 0.0):
    """Newton's ``SolverVBD`` (``"inertia"``, ``chebyshev_rho`` 0), or its subclass that
    starts each substep's sweeps with the adaptive initial guess (``"adaptive"``) and/or
    accelerates them by Chebyshev's method for a spectral radius ``chebyshev_rho`` in
    (0, 1), each extrapolated sweep truncated again as Newton truncates a sweep (so that the
    cloth stays out of itself and the body as it does)."""
    import newton

    if initial_guess not in ("inertia", "adaptive"):
        raise ValueError(f"initial_guess: expected 'inertia' or 'adaptive', got {initial_guess!r}")
    if not 0.0 <= chebyshev_rho < 1.0:
        raise ValueError(f"chebyshev_rho: expected a number in [0, 1), got {chebyshev_rho!r}")
    if initial_guess == "inertia" and chebyshev_rho == 0.0:
        return newton.solvers.SolverVBD
    adaptive = initial_guess == "adaptive"

    class FasterVBD(newton.solvers.SolverVBD):
        """Newton's VBD with the adaptive initial guess and/or Chebyshev's acceleration
        (this module's docstring)."""

        def step(self, state_in, state_out, control, contacts, dt, **kwargs):
            self._sweep = 0
            super().step(state_in, state_out, control, contacts, dt, **kwargs)

        def _initialize_particles(self, state_in, state_out, contacts, dt):
            if not adaptive:
                return super()._initialize_particles(state_in, state_out, contacts, dt)
            model = self.model
            if model.particle_count == 0:
                return
            if not hasattr(self, "_vel_before"):
                self._vel_before = wp.clone(state_in.particle_qd)
            if not self.rigid_soft_enable_dat and not self.particle_enable_self_contact:
                self.pos_prev_collision_detection.assign(state_in.particle_q)
                self.particle_displacements.zero_()
            wp.launch(
                adaptive_forward_step_kernel,
                dim=model.particle_count,
                inputs=[
                    dt,
                    model.gravity,
                    model.particle_world,
                    state_in.particle_q,
                    state_in.particle_qd,
                    self._vel_before,
                    model.particle_inv_mass,
                    state_in.particle_f,
                    model.particle_flags,
                    int(newton.ParticleFlags.ACTIVE),
                ],
                outputs=[self.particle_q_prev, self.inertia, self.particle_displacements],
                device=self.device,
            )
            self._penetration_free_truncation(state_in, contacts)

        def _solve_particle_iteration(self, state_in, state_out, contacts, dt):
            if chebyshev_rho == 0.0:
                return super()._solve_particle_iteration(state_in, state_out, contacts, dt)
            n = self._sweep
            self._sweep += 1
            if n == 0:  # the sweeps' start: the history two back
                if not hasattr(self, "_last"):
                    self._last = wp.zeros_like(self.particle_displacements)
                    self._before_last = wp.zeros_like(self.particle_displacements)
                    self._omegas = chebyshev_omegas(chebyshev_rho, self.iterations)
                wp.copy(self._before_last, self.particle_displacements)
            super()._solve_particle_iteration(state_in, state_out, contacts, dt)
            if n == 0:
                wp.copy(self._last, self.particle_displacements)
                return
            omega = self._omegas[n]
            wp.launch(
                chebyshev_kernel,
                dim=self.model.particle_count,
                inputs=[omega],
                outputs=[self.particle_displacements, self._last, self._before_last],
                device=self.device,
            )
            self._penetration_free_truncation(state_in, contacts)
            wp.copy(self._last, self.particle_displacements)
            wp.copy(state_out.particle_q, state_in.particle_q)

    return FasterVBD
