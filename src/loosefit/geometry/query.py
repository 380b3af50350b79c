"""Closest points on a triangle mesh and inside/outside tests, with warp's BVH.

These are the queries that collision handling and data-quality checks need:
for each query point, the closest point on the (watertight) body surface, the
face it lies on, and whether the point is inside the body.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from loosefit.warp_log import import_warp

wp = import_warp()  # its banner and kernel loads on standard error


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


@wp.func
def _triangle_distance(p: wp.vec3, a: wp.vec3, b: wp.vec3, c: wp.vec3) -> float:
    """The distance from ``p`` to the triangle (a, b, c) (Ericson, Real-Time Collision
    Detection 5.1.5: the closest point by the Voronoi region it lies in)."""
    ab = b - a
    ac = c - a
    ap = p - a
    d1 = wp.dot(ab, ap)
    d2 = wp.dot(ac, ap)
    bp = p - b
    d3 = wp.dot(ab, bp)
    d4 = wp.dot(ac, bp)
    cp = p - c
    d5 = wp.dot(ab, cp)
    d6 = wp.dot(ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    q = a
    if d1 <= 0.0 and d2 <= 0.0:
        q = a
    elif d3 >= 0.0 and d4 <= d3:
        q = b
    elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        q = a + ab * (d1 / (d1 - d3))
    elif d6 >= 0.0 and d5 <= d6:
        q = c
    elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        q = a + ac * (d2 / (d2 - d6))
    elif va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        q = b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)))
    else:
        denom = 1.0 / (va + vb + vc)
        q = a + ab * (vb * denom) + ac * (vc * denom)
    return wp.length(p - q)


@wp.func
def _reach(mesh: wp.uint64, p: wp.vec3, max_dist: float, hint: int, num_faces: int) -> float:
    """The distance a query at ``p`` must search: ``max_dist``, or less where the face
    ``hint`` (-1: none) is nearer (the closest face is no farther than any face): the same
    answer, from a smaller part of the BVH."""
    if hint < 0 or hint >= num_faces:
        return max_dist
    a = wp.mesh_get_point(mesh, hint * 3 + 0)
    b = wp.mesh_get_point(mesh, hint * 3 + 1)
    c = wp.mesh_get_point(mesh, hint * 3 + 2)
    return wp.min(max_dist, _triangle_distance(p, a, b, c) * 1.001 + 1.0e-5)


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
    hints: wp.array(dtype=wp.int32),
    num_hints: int,
    num_faces: int,
):
    tid = wp.tid()
    reach = max_dist
    if tid < num_hints:
        reach = _reach(mesh, queries[tid], max_dist, hints[tid], num_faces)
    # inside by the winding number (robust to small holes) or by the closest face's side
    if winding != 0:
        q = wp.mesh_query_point_sign_winding_number(mesh, queries[tid], reach, accuracy, 0.5)
        _store(mesh, q, tid, out_points, out_faces, out_bary, out_sign)
    else:
        q = wp.mesh_query_point_sign_normal(mesh, queries[tid], reach)
        _store(mesh, q, tid, out_points, out_faces, out_bary, out_sign)


# three fixed, unrelated directions for the rays' vote (none along an axis or a symmetry
# plane of a body, so no ray runs along a row of its faces' edges)
_RAY_A = wp.constant(wp.vec3(0.57357, 0.58175, 0.57673))
_RAY_B = wp.constant(wp.vec3(-0.62017, 0.41201, -0.66752))
_RAY_C = wp.constant(wp.vec3(0.23138, -0.91342, 0.33491))


@wp.func
def _ray_winding(mesh: wp.uint64, p: wp.vec3, d: wp.vec3) -> int:
    """The winding number at ``p`` as the ray ``p + t d`` (t > 0, d unit) counts it: +1 for
    each face it leaves the volume through (the face's back), -1 for each it enters through;
    each crossing point is counted once (the ray goes on from just beyond it)."""
    w = int(0)  # noqa: UP018 (warp: a variable the loop may change, not a constant)
    start = p
    for _ in range(64):
        h = wp.mesh_query_ray(mesh, start, d, 1.0e3)
        if not h.result:
            break
        if h.sign < 0.0:
            w += 1
        else:
            w -= 1
        start = start + (h.t + 1.0e-6) * d
    return w


@wp.func
def _rays_sign(mesh: wp.uint64, p: wp.vec3, closest: wp.vec3) -> float:
    """-1 where ``p`` is inside the mesh by the winding number counted along rays, +1 outside:
    a ray away from its closest skin (at ``closest``) that crosses no face starts outside
    (winding number 0); otherwise the majority of three rays' winding numbers."""
    away = p - closest
    length = wp.length(away)
    outside = False
    if length > 1.0e-6:
        outside = wp.mesh_query_ray_count_intersections(mesh, p, away / length) == 0
    sign = float(1.0)  # noqa: UP018 (warp: a variable the branch may change)
    if not outside:
        votes = int(0)  # noqa: UP018 (as in _ray_winding)
        if _ray_winding(mesh, p, _RAY_A) > 0:
            votes += 1
        if _ray_winding(mesh, p, _RAY_B) > 0:
            votes += 1
        if votes == 1 and _ray_winding(mesh, p, _RAY_C) > 0:
            votes += 1
        sign = wp.where(votes >= 2, -1.0, 1.0)
    return sign


@wp.kernel
def _rays_kernel(
    mesh: wp.uint64,
    queries: wp.array(dtype=wp.vec3),
    closest: wp.array(dtype=wp.vec3),
    faces: wp.array(dtype=wp.int32),
    out_sign: wp.array(dtype=float),
):
    tid = wp.tid()
    if faces[tid] >= 0:
        out_sign[tid] = _rays_sign(mesh, queries[tid], closest[tid])
    else:
        out_sign[tid] = 1.0


@wp.kernel
def _closest_rays_kernel(
    mesh: wp.uint64,
    queries: wp.array(dtype=wp.vec3),
    max_dist: float,
    out_points: wp.array(dtype=wp.vec3),
    out_faces: wp.array(dtype=wp.int32),
    out_bary: wp.array(dtype=wp.vec3),
    out_sign: wp.array(dtype=float),
    hints: wp.array(dtype=wp.int32),
    num_hints: int,
    num_faces: int,
):
    tid = wp.tid()
    p = queries[tid]
    reach = max_dist
    if tid < num_hints:
        reach = _reach(mesh, p, max_dist, hints[tid], num_faces)
    q = wp.mesh_query_point_no_sign(mesh, p, reach)
    if q.result:
        q.sign = _rays_sign(mesh, p, wp.mesh_eval_position(mesh, q.face, q.u, q.v))
    _store(mesh, q, tid, out_points, out_faces, out_bary, out_sign)


@wp.kernel
def _ray_kernel(
    mesh: wp.uint64,
    origins: wp.array(dtype=wp.vec3),
    directions: wp.array(dtype=wp.vec3),
    max_t: float,
    out_t: wp.array(dtype=float),
    out_faces: wp.array(dtype=wp.int32),
):
    tid = wp.tid()
    h = wp.mesh_query_ray(mesh, origins[tid], directions[tid], max_t)
    if h.result:
        out_t[tid] = h.t
        out_faces[tid] = h.face
    else:
        out_t[tid] = max_t
        out_faces[tid] = -1


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

    def __init__(
        self,
        vertices: np.ndarray,
        faces: np.ndarray,
        device: str = "cpu",
        winding_number: bool = False,
    ) -> None:
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
        self.mesh = wp.Mesh(
            points=self._points, indices=self._indices, support_winding_number=winding_number
        )
        self._buffers: tuple | None = None  # the queries' in and out arrays, grown as needed
        self._views: tuple | None = None  # their numpy views (CPU)

    def refit(self, vertices: np.ndarray) -> None:
        """Move the mesh to new vertex positions (Vb, 3), the same topology."""
        if vertices.shape != (self.num_vertices, 3):
            raise ValueError(f"vertices: expected ({self.num_vertices}, 3), found {vertices.shape}")
        self.vertices = np.array(vertices, np.float32)
        self._points.assign(self.vertices)
        self.mesh.refit()

    def query(
        self,
        queries: np.ndarray,
        max_distance: float = 1.0e3,
        sign: str = "winding",
        accuracy: float = 2.0,
        hint: np.ndarray | None = None,
    ) -> ClosestPoints:
        """Closest surface points of queries (N, 3) and an inside test; see :func:`closest_points`.

        ``sign="rays"`` decides inside by the winding number counted along rays (the faces
        each crosses, by their side: exact on a closed mesh, overlapping parts included, and
        needs no solid-angle data, so the surface refits several times faster): a ray
        away from the closest skin that meets no face says outside; otherwise the majority
        of three rays in fixed directions (the fast path of collision handling).
        ``sign="winding"`` decides inside by the generalised winding number where the
        surface keeps it (``winding_number=True``; robust to small holes and to parts
        that overlap), otherwise by warp's vote of three rays; ``"normal"`` by the side
        of the closest face's normal: several times faster, and the same on a closed
        mesh away from its creases. ``accuracy``: the fast winding number's (warp's
        ``beta``; 2 by default, 1 about a third faster with the same answers on the body
        away from its skin, 0.5 wrong by centimetres). ``hint``: (N,) a face of the mesh
        for each query (-1: none), e.g. its closest face of a query before: the search
        goes no farther than that face (the same answers, much faster where the hint is
        near).
        """
        if sign not in ("winding", "normal", "rays"):
            raise ValueError(f"sign: expected 'winding', 'normal' or 'rays', found {sign!r}")
        n = len(queries)
        q, pts, fcs, bary, signs, hints = self._arrays(n)
        num_hints = 0 if hint is None else n
        if hint is not None and np.shape(hint) != (n,):
            raise ValueError(f"hint: expected ({n},) faces, found {np.shape(hint)}")
        if self.device == "cpu":
            views = self._views  # the buffers themselves (the host's memory)
            views[0][:n] = queries
            if num_hints:
                views[5][:n] = hint
        else:
            q = wp.array(
                np.ascontiguousarray(queries, np.float32), dtype=wp.vec3, device=self.device
            )
            if num_hints:
                hints = wp.array(np.asarray(hint, np.int32), dtype=wp.int32, device=self.device)
        tail = [hints, num_hints, len(self.faces)]
        if sign == "rays":
            args = [self.mesh.id, q, float(max_distance), pts, fcs, bary, signs, *tail]
            wp.launch(_closest_rays_kernel, dim=n, inputs=args, device=self.device)
        else:
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
                    *tail,
                ],
                device=self.device,
            )
        if self.device == "cpu":
            pts, fcs, bary, signs = self._views[1:5]
        else:
            pts, fcs, bary, signs = (a.numpy() for a in (pts, fcs, bary, signs))
        points = pts[:n].copy()
        return ClosestPoints(
            points=points,
            faces=fcs[:n].astype(np.int64),
            barycentric=bary[:n].copy(),
            inside=signs[:n] < 0,
            distance=np.linalg.norm(points - np.asarray(queries, np.float32), axis=-1),
        )

    def inside_by_rays(
        self, points: np.ndarray, closest: np.ndarray, faces: np.ndarray
    ) -> np.ndarray:
        """``query(sign="rays")``'s inside test alone, for points (N, 3) whose closest surface
        points (N, 3) and faces (N,) (-1: none near, then outside) a query gave already: the
        same answers without walking the BVH for the closest points again.

        Returns:
            (N,) bool, True inside.
        """
        n = len(points)
        if np.shape(closest) != (n, 3) or np.shape(faces) != (n,):
            raise ValueError(
                f"closest, faces: expected ({n}, 3) and ({n},), found "
                f"{np.shape(closest)} and {np.shape(faces)}"
            )
        if not n:
            return np.zeros(0, dtype=bool)
        p, c = (
            wp.array(np.ascontiguousarray(a, np.float32), dtype=wp.vec3, device=self.device)
            for a in (points, closest)
        )
        f = wp.array(np.asarray(faces, np.int32), dtype=wp.int32, device=self.device)
        sign = wp.zeros(n, dtype=float, device=self.device)
        wp.launch(_rays_kernel, dim=n, inputs=[self.mesh.id, p, c, f, sign], device=self.device)
        return sign.numpy() < 0

    def first_hits(
        self, origins: np.ndarray, directions: np.ndarray, max_t: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Where the rays ``origins + t directions`` (N, 3) each, directions of unit length)
        first meet the surface, ``0 < t <= max_t``.

        Returns:
            t (N,) float32 (``max_t`` where a ray meets nothing), and the face met (N,) int64
            (-1: none).
        """
        n = len(origins)
        if np.shape(directions) != (n, 3):
            raise ValueError(f"directions: expected ({n}, 3), found {np.shape(directions)}")
        t = wp.zeros(max(n, 1), dtype=float, device=self.device)
        faces = wp.zeros(max(n, 1), dtype=wp.int32, device=self.device)
        if n:
            o, d = (
                wp.array(np.ascontiguousarray(a, np.float32), dtype=wp.vec3, device=self.device)
                for a in (origins, directions)
            )
            wp.launch(
                _ray_kernel,
                dim=n,
                inputs=[self.mesh.id, o, d, float(max_t), t, faces],
                device=self.device,
            )
        return t.numpy()[:n], faces.numpy()[:n].astype(np.int64)

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
                wp.zeros(size, dtype=wp.int32, device=device),  # the queries' hints
            )
            # on the CPU, numpy views of the same memory, made once (a view per query
            # cost ~0.1 ms a query, 1-2 ms of a frame of collision handling)
            self._views = tuple(a.numpy() for a in self._buffers) if device == "cpu" else None
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
