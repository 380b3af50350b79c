"""The cloth simulator: Newton's VBD solver on a deforming body, one substep at a time.

The garment is a Newton cloth mesh (Vertex Block Descent, He Chen et al. 2024)
and the body a collision mesh that deforms with the motion:

* **Body.** One static mesh shape holds the full-resolution, watertight anny
  body. Before every substep its ``wp.Mesh`` points are overwritten with the
  body posed for the *end* of that substep (linear interpolation between the
  frame's start and end vertices), its velocities with the frame's vertex
  velocities (for friction), and its BVH is refitted. Newton's soft contacts
  test inside/outside against a watertight mesh by ray parity, so a cloth
  vertex that ends up inside the body is pushed back out (up to
  ``body_contact_gap + body_contact_distance`` deep; deeper ones get no contact).
* **Waistband.** Its vertices are not simulated: each is glued to a point of
  the body (:mod:`loosefit.sim.waist`) and moved there before every substep.

The simulator follows Newton's pattern: a static ``Model``, two ``State``\\ s
swapped after every ``solver.step``. Warp's CPU kernels run on one thread;
the first run compiles them (about 35 s, cached under ``~/.cache/warp``).
What drives it through a clip (settle, blend, motion) is :mod:`loosefit.sim.driver`.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.sim.cloth_config import ClothConfig
from loosefit.sim.kernels import damp_kernel, pin_waist_kernel, pose_bodies_kernel
from loosefit.sim.vbd import solver_class
from loosefit.sim.waist import glue_waist
from loosefit.warp_log import import_warp

wp = import_warp()  # its banner and kernel loads on standard error


class ClothSimulator:
    """Newton VBD cloth on a deforming body: a static Model, two swapped States, a step a substep.

    One simulator can also run ``K`` clips at once (batched simulation, for a GPU): the
    garment and the body then come with a leading clip axis, and each clip is a world of
    one Newton model, with its own cloth, its own body mesh and its own waistband glue.
    Worlds keep body contacts apart; Newton's cloth self-contact does not look at
    worlds, so each world is also moved to its own cell of a grid, far enough apart that
    no two clips' cloth can meet (offsets added on the way in and taken off on the way
    out: callers see every clip in its own coordinates).

    Args:
        garment_vertices: (V, 3) initial cloth positions, world frame; or (K, V, 3),
            one garment per clip (the same mesh).
        garment_faces: (F, 3) cloth triangles; the initial positions are also the rest shape
            unless ``rest_vertices`` are given.
        waist: (W,) indices of the waistband vertices, glued to the body.
        body_vertices: (Vb, 3) the body at the start, world frame; (K, Vb, 3) batched.
        body_faces: (Fb, 3) triangles of a closed (watertight) body mesh.
        config: the physics.
        frame_dt: seconds per frame; :meth:`step_frame` divides it into ``config.substeps``
            substeps, or as many as it is given.
        bounds: (lower (3,), upper (3,)) a box that holds the body over the whole motion
            (of every clip); contacts are culled outside it. Default: the starting
            bodies' box grown by 2 m.
        loop: ``waist`` is a closed band in order (a waistband, a dress's top band),
            respaced as it is pulled onto the body; False: separate points (a dress's
            straps), each held where it is closest (see :func:`glue_waist`).
        seeds: (K,) each clip's jitter seed (default: ``config.seed`` for all).
        limb_faces: (Fl, 3) triangles of a second closed mesh on the body's vertices (the
            arms cut from ``body_faces``, :meth:`Avatar.cut_limb_faces`), a collider of its
            own with ``config.arm_friction``; None: no such collider.
        rest_vertices: (V, 3) the cloth's rest shape (edge lengths, triangle shapes and
            areas, so masses), in any rigid placement, when it is not the initial positions
            (:attr:`GarmentTemplate.rest_vertices`: a garment fitted to the avatar starts
            draped and keeps its file's rest lengths); None: the initial positions.
    """

    # with ``config.capture`` on a GPU: a whole frame as one graph (else one per substep, the
    # body posed between them); a benchmark compares the two
    record_frames: bool = True

    def __init__(
        self,
        garment_vertices: np.ndarray,
        garment_faces: np.ndarray,
        waist: np.ndarray,
        body_vertices: np.ndarray,
        body_faces: np.ndarray,
        config: ClothConfig,
        *,
        frame_dt: float,
        bounds: tuple[np.ndarray, np.ndarray] | None = None,
        loop: bool = True,
        seeds: list[int] | None = None,
        limb_faces: np.ndarray | None = None,
        rest_vertices: np.ndarray | None = None,
    ) -> None:
        import newton  # imported here: importing it takes seconds

        self.config = cfg = config
        self.frame_dt = float(frame_dt)
        self.device = wp.get_device(cfg.device)
        garment_vertices = np.asarray(garment_vertices, np.float64)
        self.batched = garment_vertices.ndim == 3
        garments = garment_vertices if self.batched else garment_vertices[None]  # (K, V, 3)
        bodies = np.asarray(body_vertices, np.float32)
        bodies = bodies if self.batched else bodies[None]  # (K, Vb, 3)
        K = self.worlds = len(garments)
        if bodies.ndim != 3 or len(bodies) != K:
            raise LoosefitInputError(
                "ClothSimulator",
                "body_vertices",
                f"({K}, Vb, 3)",
                f"shape {np.shape(body_vertices)}",
            )
        seeds = [cfg.seed] * K if seeds is None else [int(s) for s in seeds]
        if len(seeds) != K:
            raise LoosefitInputError("ClothSimulator", "seeds", f"{K} seeds", len(seeds))
        body_faces = np.ascontiguousarray(body_faces, np.int32)
        waist = np.asarray(waist, np.int64)
        V = self.num_vertices = garments.shape[1]
        if rest_vertices is not None:
            rest_vertices = np.asarray(rest_vertices, np.float64)
            if rest_vertices.shape != (V, 3):
                raise LoosefitInputError(
                    "ClothSimulator",
                    "rest_vertices",
                    f"shape ({V}, 3)",
                    f"shape {rest_vertices.shape}",
                )
        self.num_body_vertices = bodies.shape[1]
        if bounds is None:
            bounds = (bodies.min((0, 1)) - 2.0, bodies.max((0, 1)) + 2.0)
        lower = np.asarray(bounds[0], np.float32).reshape(3)
        upper = np.asarray(bounds[1], np.float32).reshape(3)
        # Each clip's cell of the grid: the bounds' size and a metre apart.
        cols = math.ceil(math.sqrt(K))
        cell = (upper - lower) + 1.0
        self.offsets = np.array(
            [[(k % cols) * cell[0], (k // cols) * cell[1], 0.0] for k in range(K)], np.float32
        )  # (K, 3)

        # 1. Glue the waistband to each clip's body, once.
        self.glues = [
            glue_waist(g[waist], b, body_faces, cfg.waist_offset, loop)
            for g, b in zip(garments, bodies, strict=True)
        ]
        self.glue = self.glues[0]

        # 2. The cloth and 3. the body, in one Newton model.
        model, start = self._build_model(
            garments,
            garment_faces,
            bodies,
            body_faces,
            seeds,
            limb_faces,
            rest_vertices=rest_vertices,
            lower=lower,
            upper=upper,
        )
        self.model = model

        # 4. The waistbands are kinematic: inactive, infinite mass.
        _pin_particles(model, (np.arange(K)[:, None] * V + waist[None]).ravel())

        # 5. Contacts, solver, the two states.
        self.pipeline = newton.CollisionPipeline(model, soft_contact_gap=cfg.body_contact_gap)
        self.contacts = self.pipeline.contacts()
        Base = newton.solvers.SolverBase
        passes = {}  # Newton's default: self-contact detected before and after the forward step
        if cfg.self_contact_passes == 1:
            passes = {Base.CollisionSlot.SOFT_SELF_CONTACT: Base.CollisionFrequencyType.PRE_INIT}
        self.solver = solver_class(cfg.initial_guess, cfg.chebyshev_rho)(
            model,
            collision_frequency_type=passes,
            iterations=cfg.iterations,
            integrate_with_external_rigid_solver=True,  # the body moves outside the solver
            particle_enable_self_contact=cfg.self_contact,
            particle_self_contact_margin=cfg.self_contact_margin,
            particle_self_contact_gap=cfg.self_contact_gap,
            particle_rest_shape_contact_exclusion_radius=cfg.self_contact_rest_exclusion,
        )
        self.state_0 = model.state()
        self.state_1 = model.state()
        self.control = model.control()
        self.state_0.particle_q.assign(start)
        self.state_1.particle_q.assign(start)

        # 6. Device buffers for the bodies' frame and the glue, per clip.
        self._device_buffers(bodies, body_faces, waist)
        self._damp_factor = wp.ones(1, dtype=float, device=self.device)
        self._graphs: dict = {}  # recorded substeps (frames on a GPU), by count and parity
        # a GPU records whole frames (until one fails to record); else substeps only
        self._frame_graphs = self.record_frames
        self._substeps = cfg.substeps  # of the frame being stepped
        self._swaps = 0
        self._pose_body(1.0)
        self._pin_waist()

    def _device_buffers(
        self, bodies: np.ndarray, body_faces: np.ndarray, waist: np.ndarray
    ) -> None:
        """The device arrays of each clip's body over a frame (start and end, moved to its
        cell of the grid) and of its waistband's glue."""
        V = self.num_vertices
        d = self.device
        self._body_faces = wp.array(body_faces, dtype=wp.vec3i, device=d)
        # every clip's body at the start and the end of the frame, in its own coordinates
        self._body_start = wp.array(bodies, dtype=wp.vec3, device=d)  # (K, Vb)
        self._body_end = wp.array(bodies, dtype=wp.vec3, device=d)
        self._offsets = wp.array(self.offsets, dtype=wp.vec3, device=d)
        self._shapes_per_world = len(self._body_meshes[0])
        self._mesh_ids = wp.array(
            [shape.mesh.id for shapes in self._body_meshes for shape in shapes],
            dtype=wp.uint64,
            device=d,
        )
        self._glue_arrays = [
            (
                wp.array(g.faces.astype(np.int32), dtype=wp.int32, device=d),
                wp.array(g.barycentric.astype(np.float32), dtype=wp.vec3, device=d),
                wp.array(g.local.astype(np.float32), dtype=wp.vec3, device=d),
                g.outward,
                wp.array((waist + k * V).astype(np.int32), dtype=wp.int32, device=d),
            )
            for k, g in enumerate(self.glues)
        ]

    def _build_model(
        self,
        garments: np.ndarray,
        garment_faces: np.ndarray,
        bodies: np.ndarray,
        body_faces: np.ndarray,
        seeds: list[int],
        limb_faces: np.ndarray | None,
        *,
        rest_vertices: np.ndarray | None,
        lower: np.ndarray,
        upper: np.ndarray,
    ) -> tuple[object, np.ndarray]:
        """The static Newton model and the cloth's starting positions (K * V, 3).

        Each clip's cloth, with a seeded jitter that breaks the template's exact symmetry,
        and its body: one static mesh shape (and one for the arms where they collide as a
        mesh of their own, ``self._body_meshes``); contact culling widened to the box
        ``lower`` .. ``upper`` of the whole motion.
        """
        import newton  # imported here: importing it takes seconds

        cfg = self.config
        K, V = self.worlds, self.num_vertices
        # Newton mixes contact materials as the mean of ke and kd and the geometric mean of
        # mu, so the body shape's mu is chosen to give sqrt(self_friction * shape_mu) =
        # body_friction (and the arms' to give arm_friction).
        builder = newton.ModelBuilder(gravity=(0.0, 0.0, cfg.gravity))
        shape_mu = cfg.body_friction**2 / cfg.self_friction if cfg.self_friction > 0 else 0.0

        def shape_config(mu: float):
            return newton.ModelBuilder.ShapeConfig(
                ke=cfg.contact_ke,
                kd=cfg.contact_kd,
                mu=mu,
                margin=0.0,
                gap=cfg.body_contact_gap,
                has_shape_collision=False,
                has_particle_collision=True,
            )

        shape_cfg = shape_config(shape_mu)
        limb_cfg = None
        if limb_faces is not None:
            if cfg.arm_friction is None:
                raise LoosefitInputError(
                    "ClothSimulator",
                    "config.arm_friction",
                    "a number when limb_faces are given",
                    "None",
                )
            limb_faces = np.ascontiguousarray(limb_faces, np.int32)
            limb_mu = cfg.arm_friction**2 / cfg.self_friction if cfg.self_friction > 0 else 0.0
            limb_cfg = shape_config(limb_mu)
        self._body_meshes = []  # per clip: the body's mesh, then the limbs' if any
        start = np.empty((K * V, 3), np.float32)
        for k in range(K):
            if K > 1:
                builder.begin_world(label=f"clip_{k}")
            off = self.offsets[k].astype(np.float64)
            builder.add_cloth_mesh(
                pos=wp.vec3(0.0, 0.0, 0.0),
                rot=wp.quat_identity(),
                scale=1.0,
                vel=wp.vec3(0.0, 0.0, 0.0),
                # the rest shape (the particles' positions are set to ``start`` below)
                vertices=[
                    wp.vec3(*v)
                    for v in (garments[k] if rest_vertices is None else rest_vertices) + off
                ],
                indices=np.asarray(garment_faces, np.int32).ravel().tolist(),
                density=cfg.density,
                tri_ke=cfg.stretch_ke,
                tri_ka=cfg.stretch_ka,
                tri_kd=cfg.stretch_kd,
                edge_ke=cfg.bend_ke,
                edge_kd=cfg.bend_kd,
                particle_radius=cfg.body_contact_distance,
            )
            rng = np.random.default_rng(seeds[k])
            start[k * V : (k + 1) * V] = (
                garments[k] + cfg.jitter * rng.standard_normal(garments[k].shape) + off
            )
            mesh = newton.Mesh(
                bodies[k] + self.offsets[k], body_faces.ravel(), compute_inertia=False
            )
            self._body_meshes.append([mesh])
            builder.add_shape_mesh(body=-1, mesh=mesh, cfg=shape_cfg)
            if limb_cfg is not None:
                limb = newton.Mesh(
                    bodies[k] + self.offsets[k], limb_faces.ravel(), compute_inertia=False
                )
                self._body_meshes[-1].append(limb)
                builder.add_shape_mesh(body=-1, mesh=limb, cfg=limb_cfg)
            if K > 1:
                builder.end_world()
        # VBD solves one colour of vertices at a time.
        builder.color(include_bending=cfg.color_bending)

        model = builder.finalize(device=self.device)
        model.soft_contact_ke = cfg.contact_ke
        model.soft_contact_kd = cfg.contact_kd
        model.soft_contact_mu = cfg.self_friction
        if cfg.flat_rest:
            model.edge_rest_angle.zero_()
        # The shapes' cached boxes are the starting bodies': widen them to the whole motion,
        # for every shape of a clip (the body, and the arms if they are a mesh of their own).
        per_world = len(self._body_meshes[0])
        if model.shape_collision_aabb_lower.shape[0] != K * per_world:  # assign would truncate
            raise RuntimeError(
                f"{model.shape_collision_aabb_lower.shape[0]} shapes in the "
                f"model, expected {K} x {per_world}"
            )
        model.shape_collision_aabb_lower.assign(np.repeat(lower[None] + self.offsets, per_world, 0))
        model.shape_collision_aabb_upper.assign(np.repeat(upper[None] + self.offsets, per_world, 0))

        return model, start

    # -- one substep at a time --------------------------------------------------

    def _pose_body(self, alpha: float) -> None:
        """Every clip's body meshes posed ``alpha`` into the frame (one launch) and refitted."""
        wp.launch(
            pose_bodies_kernel,
            dim=(len(self._mesh_ids), self.num_body_vertices),
            inputs=[
                self._body_start,
                self._body_end,
                self._offsets,
                self._shapes_per_world,
                alpha,
                1.0 / self.frame_dt,
                self._mesh_ids,
            ],
            device=self.device,
        )
        for shapes in self._body_meshes:
            for shape in shapes:
                shape.mesh.refit()

    def _pin_waist(self) -> None:
        for (body, *_), (faces, bary, local, outward, particles) in zip(
            self._body_meshes, self._glue_arrays, strict=True
        ):
            wp.launch(
                pin_waist_kernel,
                dim=len(particles),
                inputs=[
                    body.mesh.points,
                    self._body_faces,
                    faces,
                    bary,
                    local,
                    outward,
                    particles,
                ],
                outputs=[self.state_0.particle_q, self.state_1.particle_q],
                device=self.device,
            )

    def _substep(self) -> None:
        """One substep once the body is posed: device work only, so that a graph can record it."""
        dt = self.frame_dt / self._substeps
        self._pin_waist()
        self.pipeline.collide(self.state_0, self.contacts)
        self.solver.step(self.state_0, self.state_1, self.control, self.contacts, dt)
        wp.launch(
            damp_kernel,
            dim=self.worlds * self.num_vertices,
            inputs=[self._damp_factor],
            outputs=[self.state_1.particle_qd],
            device=self.device,
        )

    def step_frame(
        self,
        body_start: np.ndarray,
        body_end: np.ndarray,
        damping: float | None = None,
        substeps: int | None = None,
    ) -> None:
        """Advance one frame while the body moves linearly from ``body_start`` to ``body_end``.

        Args:
            body_start: (Vb, 3) body vertices at the start of the frame; (K, Vb, 3) batched.
            body_end: (Vb, 3) body vertices at the end of the frame; (K, Vb, 3) batched.
            damping: velocity decay rate, 1/s (default ``config.air_damping``).
            substeps: solver steps for this frame (default ``config.substeps``).
        """
        cfg = self.config
        n = cfg.substeps if substeps is None else int(substeps)
        if n < 1:
            raise ValueError(f"substeps must be >= 1, got {n}")
        self._substeps = n
        rate = cfg.air_damping if damping is None else damping
        self._damp_factor.fill_(math.exp(-rate * self.frame_dt / n))
        shape = (self.worlds, self.num_body_vertices, 3)
        self._body_start.assign(np.ascontiguousarray(body_start, np.float32).reshape(shape))
        self._body_end.assign(np.ascontiguousarray(body_end, np.float32).reshape(shape))
        self.solver.rebuild_bvh(self.state_0)  # self-contact BVH, rebuilt once a frame
        frame_graph = cfg.capture and self.device.is_cuda and self._frame_graphs
        if frame_graph and self._swaps >= 2 and self._replay_frame(n):
            return
        for s in range(n):
            # Pose the body for the end of the substep before detecting contacts against it.
            # (Outside any graph: a CPU graph does not replay wp.Mesh.refit.)
            self._pose_body((s + 1) / n)
            if cfg.capture and self._swaps >= 2:
                # One graph per direction of the swap, state_0 -> state_1 and back, recorded
                # after a plain substep each (which allocates whatever the solver allocates
                # lazily).
                # The substep length is baked into a graph: one pair per substep count.
                slot = (n, self._swaps % 2)
                if slot not in self._graphs:
                    with wp.ScopedCapture(device=self.device) as capture:
                        self._substep()
                    self._graphs[slot] = capture.graph
                wp.capture_launch(self._graphs[slot])
            else:
                self._substep()
            self.state_0, self.state_1 = self.state_1, self.state_0
            self._swaps += 1

    def _replay_frame(self, n: int) -> bool:
        """On a GPU, a whole frame of ``n`` substeps (the body posed and refitted, the
        waistband, contacts, the solver, the damping) as one recorded CUDA graph: no host
        work between substeps. One graph per substep count and parity of the swap; a frame
        that cannot be recorded (a warp or driver that refuses a refit in a graph) falls
        back to the substep graphs for the rest of the run."""
        slot = ("frame", n, self._swaps % 2)
        if slot not in self._graphs:
            states = (self.state_0, self.state_1, self._swaps)
            try:
                with wp.ScopedCapture(device=self.device) as capture:
                    self._frame_substeps(n)
            except Exception as exc:  # nothing ran: the substep graphs from here on
                self.state_0, self.state_1, self._swaps = states
                self._frame_graphs = False
                warnings.warn(
                    f"a frame could not be recorded as one graph ({type(exc).__name__}: "
                    f"{exc}); recording each substep instead",
                    RuntimeWarning,
                    stacklevel=2,
                )
                return False
            self._graphs[slot] = capture.graph
            self.state_0, self.state_1, self._swaps = states
        wp.capture_launch(self._graphs[slot])
        for _ in range(n):  # what the recorded frame did to the two states
            self.state_0, self.state_1 = self.state_1, self.state_0
            self._swaps += 1
        return True

    def _frame_substeps(self, n: int) -> None:
        for s in range(n):
            self._pose_body((s + 1) / n)
            self._substep()
            self.state_0, self.state_1 = self.state_1, self.state_0
            self._swaps += 1

    def _per_clip(self, x: np.ndarray, sign: float) -> np.ndarray:
        """(K * V, 3) particle positions to (K, V, 3) or (V, 3), offsets taken off (sign -1)."""
        x = x.reshape(self.worlds, self.num_vertices, 3) + sign * self.offsets[:, None]
        return x if self.batched else x[0]

    @property
    def positions(self) -> np.ndarray:
        """(V, 3) float32 current cloth positions (a copy); (K, V, 3) batched."""
        return self._per_clip(self.state_0.particle_q.numpy(), -1.0).astype(np.float32)

    def get_state(self) -> tuple[np.ndarray, np.ndarray]:
        """(V, 3) float32 positions and (V, 3) float32 velocities (a leading K batched): all
        the solver carries over."""
        qd = self.state_0.particle_qd.numpy().reshape(self.worlds, self.num_vertices, 3)
        return self.positions, (qd if self.batched else qd[0]).copy()

    def set_state(self, positions: np.ndarray, velocities: np.ndarray) -> None:
        """Continue from a state taken by :meth:`get_state` (after the same number of frames)."""
        q = np.asarray(positions, np.float32).reshape(self.worlds, self.num_vertices, 3)
        q = (q + self.offsets[:, None]).reshape(-1, 3)
        qd = np.asarray(velocities, np.float32).reshape(-1, 3)
        for state in (self.state_0, self.state_1):
            state.particle_q.assign(np.ascontiguousarray(q))
            state.particle_qd.assign(np.ascontiguousarray(qd))


def _pin_particles(model, pinned: np.ndarray) -> None:
    """Make the particles ``pinned`` kinematic: inactive, infinite mass."""
    import newton

    flags = model.particle_flags.numpy()
    flags[pinned] &= ~int(newton.ParticleFlags.ACTIVE)
    model.particle_flags.assign(flags)
    inv_mass = model.particle_inv_mass.numpy()
    inv_mass[pinned] = 0.0
    model.particle_inv_mass.assign(inv_mass)
