"""How deep the garment is inside the body, frame by frame.

One BVH of the body is built once and refitted to each frame's pose; each frame's garment
vertices are queried against it (:class:`~loosefit.geometry.query.Surface`): the closest
skin, the distance to it, and whether the vertex is inside.

* :func:`body_surfaces`: the body's BVH refitted to each frame in turn;
* :func:`body_hits`: the query of every frame, one after the other;
* :func:`inside_depths`: per frame, the share of vertices inside and the deepest of them.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from loosefit.geometry.query import ClosestPoints, Surface


def body_surfaces(
    body: np.ndarray, faces: np.ndarray, winding_number: bool = False
) -> Iterator[Surface]:
    """The body's surface at each frame: one BVH, built once and refitted frame by frame.

    Args:
        body: (T, Vb, 3) the posed body.
        faces: (Fb, 3) its triangles (closed, facing out).
        winding_number: keep the BVH's solid-angle data (inside by the generalised winding
            number).

    Yields:
        T times the same :class:`~loosefit.geometry.query.Surface`, refitted to frame t
        (valid until the next frame is asked for).
    """
    if len(body) == 0:
        return
    surface = Surface(body[0], faces, winding_number=winding_number)
    for t in range(len(body)):
        surface.refit(body[t])
        yield surface


def body_hits(
    garment: np.ndarray,
    body: np.ndarray,
    faces: np.ndarray,
    max_distance: float = 1.0e3,
    winding_number: bool = False,
) -> Iterator[ClosestPoints]:
    """The closest body point of every garment vertex, frame by frame.

    Args:
        garment: (T, V, 3) garment vertices (m), finite.
        body: (T, Vb, 3) the posed body, the same frames.
        faces: (Fb, 3) the body's triangles (closed, facing out).
        max_distance: m; vertices farther from the body have no closest face (-1).
        winding_number: decide inside by the generalised winding number (robust where body
            parts overlap, e.g. a forearm pressed into the hip) instead of warp's vote of
            three rays.

    Yields:
        T :class:`~loosefit.geometry.query.ClosestPoints`, one per frame, each of V queries.
    """
    surfaces = body_surfaces(body[: len(garment)], faces, winding_number)
    for t, surface in enumerate(surfaces):
        yield surface.query(garment[t], max_distance)


def inside_depths(
    garment: np.ndarray,
    body: np.ndarray,
    faces: np.ndarray,
    max_distance: float = 0.3,
    winding_number: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """Per frame, the share of garment vertices inside the body and the deepest one.

    Args:
        garment: (T, V, 3) garment vertices (m).
        body: (T, Vb, 3) the posed body, the same frames.
        faces: (Fb, 3) the body's triangles.
        max_distance: m; a vertex farther than this from the skin counts as outside.
        winding_number: as :func:`body_hits` (by default the generalised winding number: a
            vertex in the hip under a forearm pressed into it is inside).

    Returns:
        ``(share, deepest)``: (T,) the fraction of vertices inside, and (T,) the largest
        distance (m) of an inside vertex to the skin (0 in a frame with none inside).
    """
    share, deep = np.zeros(len(garment)), np.zeros(len(garment))
    hits = body_hits(garment, body, faces, max_distance, winding_number)
    for t, hit in enumerate(hits):
        ins = hit.inside & (hit.faces >= 0)
        share[t] = ins.mean()
        deep[t] = float(hit.distance[ins].max()) if ins.any() else 0.0
    return share, deep
