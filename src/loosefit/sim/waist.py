"""The waistband's glue: where each waistband vertex is held on the moving body.

Its vertices are not simulated: each is glued to a point of the body (a face,
barycentric coordinates and an offset in the face's frame, found once, at the start)
and moved there before every substep. By default the band is first pulled onto the
body, ``waist_offset`` outside it and respaced along its length (:func:`glue_waist`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from loosefit.geometry.query import closest_points


def _signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Volume enclosed by a closed mesh: positive when its faces wind counter-clockwise outside."""
    a, b, c = (vertices[faces[:, i]].astype(np.float64) for i in range(3))
    return float(np.einsum("ij,ij->", a, np.cross(b, c)) / 6.0)


@dataclass
class WaistGlue:
    """Where each waistband vertex is held on the body.

    The point is ``sum(barycentric * face corners) + local @ (t1, t2, n)`` with
    ``(t1, t2, n)`` the face's frame (first edge, in-plane perpendicular, outward
    normal), so it follows the skin as the body moves and bends.

    Attributes:
        faces: (W,) body face of each waistband vertex (its closest at the start).
        barycentric: (W, 3) weights of the closest point on that face.
        local: (W, 3) offset from the closest point in the face's frame.
        outward: +1 if the body's faces wind counter-clockwise seen from outside, else -1.
    """

    faces: np.ndarray
    barycentric: np.ndarray
    local: np.ndarray
    outward: float


def _resample_like(curve: np.ndarray, like: np.ndarray) -> np.ndarray:
    """Points on the closed polyline ``curve`` (N, 3) at the arc-length fractions of ``like``."""

    def fractions(c: np.ndarray) -> tuple[np.ndarray, float]:
        seg = np.linalg.norm(np.roll(c, -1, 0) - c, axis=-1)  # segment i: c[i] -> c[i + 1]
        return np.concatenate([[0.0], np.cumsum(seg)]) / seg.sum(), seg.sum()

    s_curve, _ = fractions(curve)
    s_like, _ = fractions(like)
    closed = np.concatenate([curve, curve[:1]])  # (N + 1, 3)
    return np.stack([np.interp(s_like[:-1], s_curve, closed[:, k]) for k in range(3)], -1)


def glue_waist(
    waist_points: np.ndarray,
    body_vertices: np.ndarray,
    body_faces: np.ndarray,
    offset: float | None,
    loop: bool = True,
) -> WaistGlue:
    """Glue a waistband (a closed loop of points, in order) to the body surface.

    With ``offset`` None each point keeps its offset from its closest body point,
    in that face's frame: the band is held exactly as placed. With an ``offset``,
    the band is pulled onto the body: the loop is projected onto the surface,
    respaced along its length as the original points were (projection bunches
    points where the body is flatter than the band), and each point is held
    ``offset`` outside its closest surface point along the normal.

    Args:
        waist_points: (W, 3) waistband vertices placed on the body, in loop order.
        body_vertices: (Vb, 3) the body as the waistband is placed on it.
        body_faces: (Fb, 3) triangles of the closed body mesh.
        offset: metres outside the surface; None keeps each point's own offset.
        loop: the points are a closed band in order (respaced along it); False: separate
            points (a dress's straps), each projected alone.

    Returns:
        The :class:`WaistGlue`; :func:`glued_points` evaluates it on a posed body.
    """
    placed = np.asarray(waist_points, np.float64)
    points = placed
    if offset is not None and loop and len(points) >= 3:
        for _ in range(4):  # projecting moves the respaced points a little: repeat
            surface = closest_points(body_vertices, body_faces, points).points.astype(np.float64)
            points = _resample_like(surface, placed)
    hit = closest_points(body_vertices, body_faces, points)
    outward = 1.0 if _signed_volume(body_vertices, body_faces) > 0 else -1.0
    t1, t2, n = _face_frames(body_vertices, body_faces[hit.faces], outward)  # (W, 3) each
    delta = points - hit.points
    local = np.stack([(delta * t).sum(-1) for t in (t1, t2, n)], axis=-1)  # (W, 3)
    if offset is not None:
        local[:, :2] = 0.0
        local[:, 2] = offset
    return WaistGlue(hit.faces, hit.barycentric.astype(np.float64), local, outward)


def _face_frames(
    vertices: np.ndarray, corners: np.ndarray, outward: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frames (t1, t2, n), each (N, 3), of the faces with corner indices (N, 3): the numpy
    twin of the stepper's kernel (:mod:`loosefit.sim.kernels`)."""
    x0, x1, x2 = (np.asarray(vertices, np.float64)[corners[:, i]] for i in range(3))
    t1 = (x1 - x0) / np.linalg.norm(x1 - x0, axis=-1, keepdims=True)
    n = np.cross(x1 - x0, x2 - x0)
    n = outward * n / np.linalg.norm(n, axis=-1, keepdims=True)
    return t1, np.cross(n, t1), n


def glued_points(glue: WaistGlue, body_vertices: np.ndarray, body_faces: np.ndarray) -> np.ndarray:
    """(W, 3) the glued waistband points on a posed body (Vb, 3) (numpy twin of the kernel)."""
    corners = body_faces[glue.faces]  # (W, 3)
    x = np.asarray(body_vertices, np.float64)[corners]  # (W, 3 corners, 3)
    t1, t2, n = _face_frames(body_vertices, corners, glue.outward)
    surface = (glue.barycentric[:, :, None] * x).sum(1)
    return surface + glue.local[:, :1] * t1 + glue.local[:, 1:2] * t2 + glue.local[:, 2:] * n
