"""The stepper's warp kernels on the CPU, each against the arithmetic written out in numpy."""

from __future__ import annotations

import numpy as np

from loosefit.sim.kernels import damp_kernel, pin_waist_kernel, pose_bodies_kernel
from loosefit.warp_log import import_warp

wp = import_warp()


def test_damping_scales_every_velocity():
    qd = np.array([[1.0, -2.0, 0.5], [0.0, 3.0, -4.0]], np.float32)
    arr = wp.array(qd, dtype=wp.vec3, device="cpu")
    wp.launch(damp_kernel, dim=2, inputs=[wp.array([0.25], dtype=float, device="cpu"), arr])
    np.testing.assert_allclose(arr.numpy(), qd * 0.25, rtol=1e-7)


def test_bodies_are_posed_a_fraction_into_the_frame_in_their_clip_s_cell():
    rng = np.random.default_rng(0)
    worlds, shapes, n = 2, 2, 3  # two clips, two meshes each, three vertices a mesh
    start = rng.normal(size=(worlds, n, 3)).astype(np.float32)
    end = start + rng.normal(size=(worlds, n, 3)).astype(np.float32)
    offsets = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]], np.float32)
    meshes = [
        wp.Mesh(
            points=wp.zeros(n, dtype=wp.vec3, device="cpu"),
            indices=wp.array([0, 1, 2], dtype=wp.int32, device="cpu"),
            velocities=wp.zeros(n, dtype=wp.vec3, device="cpu"),
        )
        for _ in range(worlds * shapes)
    ]
    alpha, inv_dt = 0.25, 30.0
    wp.launch(
        pose_bodies_kernel,
        dim=(worlds * shapes, n),
        inputs=[
            wp.array(start, dtype=wp.vec3, device="cpu"),
            wp.array(end, dtype=wp.vec3, device="cpu"),
            wp.array(offsets, dtype=wp.vec3, device="cpu"),
            shapes,
            alpha,
            inv_dt,
            wp.array([m.id for m in meshes], dtype=wp.uint64, device="cpu"),
        ],
        device="cpu",
    )
    for j, mesh in enumerate(meshes):  # mesh j belongs to clip j // shapes
        k = j // shapes
        want = start[k] + offsets[k] + alpha * (end[k] - start[k])
        np.testing.assert_allclose(mesh.points.numpy(), want, atol=1e-5, err_msg=f"mesh {j}")
        np.testing.assert_allclose(mesh.velocities.numpy(), (end[k] - start[k]) * inv_dt, rtol=1e-5)


def test_the_waist_is_pinned_at_its_barycentric_point_and_offset_in_the_face_s_frame():
    points = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0], [5, 5, 5]], np.float32)
    faces = np.array([[0, 1, 2]], np.int32)
    bary = np.array([[0.5, 0.25, 0.25]], np.float32)
    local = np.array([[0.1, 0.2, 0.3]], np.float32)  # along the first edge, in plane, normal
    q0 = wp.zeros(3, dtype=wp.vec3, device="cpu")
    q1 = wp.zeros(3, dtype=wp.vec3, device="cpu")
    for outward, normal in ((1.0, [0, 0, 1]), (-1.0, [0, 0, -1])):
        wp.launch(
            pin_waist_kernel,
            dim=1,
            inputs=[
                wp.array(points, dtype=wp.vec3, device="cpu"),
                wp.array(faces, dtype=wp.vec3i, device="cpu"),
                wp.array([0], dtype=wp.int32, device="cpu"),
                wp.array(bary, dtype=wp.vec3, device="cpu"),
                wp.array(local, dtype=wp.vec3, device="cpu"),
                outward,
                wp.array([2], dtype=wp.int32, device="cpu"),  # the waist's particle 2
                q0,
                q1,
            ],
            device="cpu",
        )
        # the point 0.5 x0 + 0.25 x1 + 0.25 x2 = (0.5, 0.5, 0); t1 = +x, n = +-z, t2 = n x t1
        t1, n = np.array([1.0, 0, 0]), np.array(normal, float)
        want = np.array([0.5, 0.5, 0]) + 0.1 * t1 + 0.2 * np.cross(n, t1) + 0.3 * n
        for q in (q0, q1):
            np.testing.assert_allclose(q.numpy()[2], want, atol=1e-6, err_msg=str(outward))
            np.testing.assert_array_equal(q.numpy()[:2], 0.0)  # the other particles untouched
