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


@wp.func
def _store(
    mesh: wp.uint64,
    q: wp.MeshQueryPoint,
    tid: int,
    out_points: wp.array(dtype=wp.vec3),
    out_faces: wp.array(dtype=wp.int32),
    out_bary: wp.array(dtype=wp.vec3),
    out_sign: wp.array(dtype=float),
):
    if q.result:
        out_points[tid] = wp.mesh_eval_position(mesh, q.face, q.u, q.v)
        out_faces[tid] = q.face
        out_bary[tid] = wp.vec3(q.u, q.v, 1.0 - q.u - q.v)
        out_sign[tid] = q.sign
    else:  # every field written: the arrays are reused from query to query
        out_points[tid] = wp.vec3(0.0, 0.0, 0.0)
        out_faces[tid] = -1
        out_bary[tid] = wp.vec3(0.0, 0.0, 0.0)
        out_sign[tid] = 1.0


@wp.kernel
def _closest_kernel(
    mesh: wp.uint64,
    queries: wp.array(dtype=wp.vec3),
    max_dist: float,
    out_points: wp.array(dtype=wp.vec3),
    out_faces: wp.array(dtype=wp.int32),
    out_bary: wp.array(dtype=wp.vec3),
    out_sign: wp.array(dtype=float),
    winding: int,
    accuracy: float,
):
    tid = wp.tid()
    # inside by the winding number (robust to small holes) or by the closest face's side
    if winding != 0:
        q = wp.mesh_query_point_sign_winding_number(mesh, queries[tid], max_dist, accuracy, 0.5)
        _store(mesh, q, tid, out_points, out_faces, out_bary, out_sign)
    else:
        q = wp.mesh_query_point_sign_normal(mesh, queries[tid], max_dist)
        _store(mesh, q, tid, out_points, out_faces, out_bary, out_sign)


class Surface:
    """A triangle mesh held in one warp BVH, for many closest-point queries.

    Build it once per mesh topology and :meth:`refit` it to each new pose (a
    posed body frame after frame): refitting moves the BVH's boxes instead of
    building it again.

    Args:
        vertices: (Vb, 3) mesh vertices.
        faces: (F, 3) triangles.
        device: warp device ("cpu" or "cuda:0").
        winding_number: keep the BVH's solid-angle data (refitted with it), so that
            ``sign="winding"`` is the generalised winding number. Without it warp decides
            inside by a vote of three axis rays, each by the side of the first face it
            meets, which calls a point in the hip outside when the rays meet the skin of a
            forearm pressed into the hip first; refitting costs several times as much
            with it.

    Attributes:
        vertices: (Vb, 3) float32, the current positions (host copy).
        faces: (F, 3) int64.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, device: str = "cpu",
                 winding_number: bool = False) -> None:  # fmt: skip
        self.device = device
        self.winding_number = winding_number
        self.num_vertices = len(vertices)
        self.vertices = np.array(vertices, np.float32)
        self.faces = np.asarray(faces, np.int64)
        self._points = wp.array(
            np.ascontiguousarray(vertices, np.float32), dtype=wp.vec3, device=device
        )
        self._indices = wp.array(
            np.ascontiguousarray(faces, np.int32).ravel(), dtype=wp.int32, device=device
        )
        self.mesh = wp.Mesh(points=self._points, indices=self._indices,
                            support_winding_number=winding_number)  # fmt: skip
        self._buffers: tuple | None = None  # the queries' in and out arrays, grown as needed

    def refit(self, vertices: np.ndarray) -> None:
        """Move the mesh to new vertex positions (Vb, 3), the same topology."""
        if vertices.shape != (self.num_vertices, 3):
            raise ValueError(f"vertices: expected ({self.num_vertices}, 3), found {vertices.shape}")
        self.vertices = np.array(vertices, np.float32)
        self._points.assign(self.vertices)
        self.mesh.refit()

    def query(
        self, queries: np.ndarray, max_distance: float = 1.0e3, sign: str = "winding",
        accuracy: float = 2.0,
    ) -> ClosestPoints:  # fmt: skip
        """Closest surface points of queries (N, 3) and an inside test; see :func:`closest_points`.

        ``sign="winding"`` decides inside by the generalised winding number where the
        surface keeps it (``winding_number=True``; robust to small holes and to parts
        that overlap), otherwise by warp's vote of three rays; ``"normal"`` by the side
        of the closest face's normal: several times faster, and the same on a closed
        mesh away from its creases. ``accuracy``: the fast winding number's (warp's
        ``beta``; 2 by default, 1 about a third faster with the same answers on the body
        away from its skin, 0.5 wrong by centimetres).
        """
        if sign not in ("winding", "normal"):
            raise ValueError(f"sign: expected 'winding' or 'normal', found {sign!r}")
        n = len(queries)
        q, pts, fcs, bary, signs = self._arrays(n)
        if self.device == "cpu":
            q.numpy()[:n] = queries  # the buffer itself (the host's memory)
        else:
            q = wp.array(np.ascontiguousarray(queries, np.float32), dtype=wp.vec3,
                         device=self.device)  # fmt: skip
        wp.launch(
            _closest_kernel,
            dim=n,
            inputs=[
                self.mesh.id,
                q,
                float(max_distance),
                pts,
                fcs,
                bary,
                signs,
                int(sign == "winding"),
                float(accuracy),
            ],
            device=self.device,
        )
        points = pts.numpy()[:n].copy()
        return ClosestPoints(
            points=points,
            faces=fcs.numpy()[:n].astype(np.int64),
            barycentric=bary.numpy()[:n].copy(),
            inside=signs.numpy()[:n] < 0,
            distance=np.linalg.norm(points - np.asarray(queries, np.float32), axis=-1),
        )

    def _arrays(self, n: int) -> tuple:
        """The queries' arrays, at least ``n`` long: made once and kept (on the CPU a query's
        own arrays cost more than a small query itself)."""
        if self._buffers is None or len(self._buffers[0]) < n:
            size, device = max(64, 1 << max(n - 1, 0).bit_length()), self.device
            self._buffers = (
                wp.zeros(size, dtype=wp.vec3, device=device),
                wp.zeros(size, dtype=wp.vec3, device=device),
                wp.zeros(size, dtype=wp.int32, device=device),
                wp.zeros(size, dtype=wp.vec3, device=device),
                wp.zeros(size, dtype=float, device=device),
            )
        return self._buffers


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
    return Surface(vertices, faces, device).query(queries, max_distance)
