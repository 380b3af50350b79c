"""Signed distances of points to a posed body: pure queries over a
:class:`~loosefit.geometry.query.Surface` (the collision stage,
:mod:`loosefit.inference.stages.collision`, and the collision loss ask them).

``ds = n . (x - b)``, ``b`` the closest body point and ``n`` the distance's gradient: minus
inside (by the closest face's side), +inf beyond a query's reach.
"""

from __future__ import annotations

import numpy as np

from loosefit.geometry.query import Surface


def hit_distances(hit) -> np.ndarray:
    """(N,) the signed distances of a query's answer: minus inside (by its ``inside``),
    +inf where no face was within its reach."""
    return np.where(hit.faces >= 0, np.where(hit.inside, -hit.distance, hit.distance), np.inf)


def face_normals(body: Surface, faces: np.ndarray) -> np.ndarray:
    """(K, 3) float64 outward normals, unnormalised (twice the area long), of the body's
    faces (K,)."""
    tri = body.vertices[body.faces[faces]].astype(np.float64)  # (K, 3, 3)
    return np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])


def on_skin(x: np.ndarray, body: Surface, hit, inside: np.ndarray, reach: float) -> np.ndarray:
    """(K,) bool: which of the points ``x`` (K, 3), the answers ``hit`` of whose ``inside``
    (N,) bool mask are theirs, lie on the outer side of their closest face, nearer it than
    ``reach``."""
    side = ((x - hit.points[inside]) * face_normals(body, hit.faces[inside])).sum(1)
    return (side > 0) & (hit.distance[inside] < reach)


# m: a point this close to its closest skin point lies on the skin (float32 query rounding):
# the way from it to the skin is noise, and its closest face's normal is the way out
ON_SKIN = 1e-6


def beyond_skin(
    x: np.ndarray, hit, inside: np.ndarray, epsilon: float, body: Surface
) -> tuple[np.ndarray, np.ndarray]:
    """The points ``x`` (K, 3), the answers ``hit`` of whose ``inside`` (N,) bool mask are
    theirs, moved to ``epsilon`` beyond their closest skin; and the unit directions (K, 3)
    from each toward that skin (for a point on the skin, within :data:`ON_SKIN`, its
    closest face's outward normal of ``body``)."""
    p = hit.points[inside].astype(np.float64)
    to = p - x
    length = np.linalg.norm(to, axis=1, keepdims=True)
    out = to / np.maximum(length, 1e-12)
    flat = length[:, 0] <= ON_SKIN
    if flat.any():
        fn = face_normals(body, hit.faces[inside][flat])
        out[flat] = fn / np.maximum(np.linalg.norm(fn, axis=-1, keepdims=True), 1e-30)
    return p + epsilon * out, out


def signed_distances(x: np.ndarray, body: Surface, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Normals n (N, 3) and signed distances ``ds = n.(x - b)`` (N,) of points x (N, 3),
    b their closest body points; ``ds`` is +inf (and n 0) beyond ``reach`` of the body. ``n`` is the
    distance's gradient, so ``ds = +-|x - b|`` (minus inside, by the closest face's
    side); for a point on the surface itself, the face's normal."""
    return normals_of_hit(x, body, body.query(x, reach, sign="normal"))


def normals_of_hit(x: np.ndarray, body: Surface, hit) -> tuple[np.ndarray, np.ndarray]:
    """:func:`signed_distances` of points x (N, 3) from their query's answer ``hit``."""
    valid = hit.faces >= 0
    side = np.where(hit.inside, -1.0, 1.0)[:, None]
    away = (x - hit.points) * side
    dist = hit.distance[:, None]
    n = away / np.maximum(dist, 1e-12)
    flat = valid & (hit.distance <= 1e-5)
    if flat.any():  # on the surface: the closest face's normal
        fn = face_normals(body, hit.faces[flat])
        n[flat] = fn / np.maximum(np.linalg.norm(fn, axis=-1, keepdims=True), 1e-30)
    ds = np.where(valid, (n * (x - hit.points)).sum(-1), np.inf)
    n[~valid] = 0.0
    return n, ds
