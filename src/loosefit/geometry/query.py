"""Closest points on a triangle mesh and inside/outside tests, with warp's BVH.

These are the queries that collision handling and data-quality checks need:
for each query point, the closest point on the (watertight) body surface, the
face it lies on, and whether the point is inside the body.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp


@dataclass
class ClosestPoints:
    """Result of :func:`closest_points`.

    Attributes:
        points: (N, 3) closest points on the surface.
        faces: (N,) index of the face each closest point lies on.
        barycentric: (N, 3) barycentric coordinates of the closest point in that face.
        inside: (N,) True where the query point is inside the (closed) mesh.
        distance: (N,) unsigned distance from the query to the closest point.
    """

    points: np.ndarray
    faces: np.ndarray
    barycentric: np.ndarray
    inside: np.ndarray
    distance: np.ndarray


@wp.kernel
def _closest_kernel(
    mesh: wp.uint64,
    queries: wp.array(dtype=wp.vec3),
    max_dist: float,
    out_points: wp.array(dtype=wp.vec3),
    out_faces: wp.array(dtype=wp.int32),
    out_bary: wp.array(dtype=wp.vec3),
    out_sign: wp.array(dtype=float),
):
    tid = wp.tid()
    q = wp.mesh_query_point_sign_winding_number(mesh, queries[tid], max_dist)
    if q.result:
        p = wp.mesh_eval_position(mesh, q.face, q.u, q.v)
        out_points[tid] = p
        out_faces[tid] = q.face
        out_bary[tid] = wp.vec3(q.u, q.v, 1.0 - q.u - q.v)
        out_sign[tid] = q.sign
    else:
        out_faces[tid] = -1
        out_sign[tid] = 1.0


def closest_points(
    vertices: np.ndarray,
    faces: np.ndarray,
    queries: np.ndarray,
    max_distance: float = 1.0e3,
    device: str = "cpu",
) -> ClosestPoints:
    """Closest surface points and an inside test (winding number, robust to small holes).

    Args:
        vertices: (Vb, 3) mesh vertices.
        faces: (F, 3) triangles.
        queries: (N, 3) query points.
        max_distance: queries farther than this from the surface get face -1.
        device: warp device ("cpu" or "cuda:0").

    Returns:
        :class:`ClosestPoints`; ``barycentric`` weights the face's (v0, v1, v2).
    """
    mesh = wp.Mesh(
        points=wp.array(np.ascontiguousarray(vertices, np.float32), dtype=wp.vec3, device=device),
        indices=wp.array(
            np.ascontiguousarray(faces, np.int32).ravel(), dtype=wp.int32, device=device
        ),
    )
    n = len(queries)
    q = wp.array(np.ascontiguousarray(queries, np.float32), dtype=wp.vec3, device=device)
    pts = wp.zeros(n, dtype=wp.vec3, device=device)
    fcs = wp.zeros(n, dtype=wp.int32, device=device)
    bary = wp.zeros(n, dtype=wp.vec3, device=device)
    sign = wp.zeros(n, dtype=float, device=device)
    wp.launch(
        _closest_kernel,
        dim=n,
        inputs=[mesh.id, q, float(max_distance)],
        outputs=[pts, fcs, bary, sign],
        device=device,
    )
    points = pts.numpy()
    return ClosestPoints(
        points=points,
        faces=fcs.numpy().astype(np.int64),
        barycentric=bary.numpy(),
        inside=sign.numpy() < 0,
        distance=np.linalg.norm(points - np.asarray(queries, np.float32), axis=-1),
    )
