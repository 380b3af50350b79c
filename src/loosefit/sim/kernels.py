"""The warp kernels of the stepper (:class:`~loosefit.sim.stepper.ClothSimulator`): the body
posed inside a frame, the waistband pinned to it, the velocities damped."""

from __future__ import annotations

from loosefit.warp_log import import_warp

wp = import_warp()  # its banner and kernel loads on standard error


@wp.kernel
def pose_bodies_kernel(
    start: wp.array2d(dtype=wp.vec3),
    end: wp.array2d(dtype=wp.vec3),
    offsets: wp.array(dtype=wp.vec3),
    shapes_per_world: int,
    alpha: float,
    inv_frame_dt: float,
    meshes: wp.array(dtype=wp.uint64),
):
    """Every clip's body meshes a fraction ``alpha`` into the frame, moved to the clip's cell
    of the grid, and their (constant) velocities: one thread per (mesh, body vertex); the
    meshes of clip k are ``meshes[k * shapes_per_world ...]``, all on the same vertices."""
    j, i = wp.tid()
    k = j // shapes_per_world
    a = start[k, i]
    d = end[k, i] - a
    mesh = wp.mesh_get(meshes[j])
    mesh.points[i] = a + offsets[k] + alpha * d
    mesh.velocities[i] = d * inv_frame_dt


@wp.func
def _face_frame(x0: wp.vec3, x1: wp.vec3, x2: wp.vec3, outward: float):
    """A face's orthonormal frame: first edge, in-plane normal to it, outward normal."""
    t1 = wp.normalize(x1 - x0)
    n = outward * wp.normalize(wp.cross(x1 - x0, x2 - x0))
    return t1, wp.cross(n, t1), n


@wp.kernel
def pin_waist_kernel(
    points: wp.array(dtype=wp.vec3),
    body_faces: wp.array(dtype=wp.vec3i),
    glue_faces: wp.array(dtype=wp.int32),
    glue_bary: wp.array(dtype=wp.vec3),
    glue_local: wp.array(dtype=wp.vec3),
    outward: float,
    waist_particles: wp.array(dtype=wp.int32),
    q0: wp.array(dtype=wp.vec3),
    q1: wp.array(dtype=wp.vec3),
):
    """Move each waistband particle to its glued point (see :class:`WaistGlue`)."""
    i = wp.tid()
    f = body_faces[glue_faces[i]]
    x0 = points[f[0]]
    x1 = points[f[1]]
    x2 = points[f[2]]
    t1, t2, n = _face_frame(x0, x1, x2, outward)
    b = glue_bary[i]
    o = glue_local[i]
    p = b[0] * x0 + b[1] * x1 + b[2] * x2 + o[0] * t1 + o[1] * t2 + o[2] * n
    q0[waist_particles[i]] = p
    q1[waist_particles[i]] = p


@wp.kernel
def damp_kernel(factor: wp.array(dtype=float), qd: wp.array(dtype=wp.vec3)):
    """Velocities scaled by ``factor[0]``: the air's (or the settling's) damping over a substep."""
    i = wp.tid()
    qd[i] = qd[i] * factor[0]
