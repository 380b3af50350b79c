"""How plausible a garment sequence is on its body: penetration, edge strain, speed.

The simulation's quality figures (what ``loosefit simulate`` records per clip and flags
clips by) and the same figures for any learned rollout.
"""

from __future__ import annotations

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.geometry.edges import unique_edges
from loosefit.geometry.query import closest_points
from loosefit.types import GarmentTemplate

# m: cloth less deep inside the body than this is pressed into a crease of the skin
PENETRATION_TOLERANCE = 0.005


def edge_strain(
    garment_vertices: np.ndarray, template: GarmentTemplate
) -> tuple[np.ndarray, np.ndarray]:
    """``|length / rest_length - 1|`` of every edge but those along the waistband.

    Args:
        garment_vertices: (T, V, 3) garment positions.
        template: the rest shape (edge rest lengths), faces and waistband; the body
            sets the length of the waistband's own edges, so they are left out.

    Returns:
        strain (T, E) and the edges (E, 2) it measures.
    """
    g = np.asarray(garment_vertices, np.float32)
    edges, _ = unique_edges(template.faces)
    edges = edges[~np.isin(edges, template.waist).all(1)]
    r = template.rest
    rest = np.linalg.norm(r[edges[:, 0]] - r[edges[:, 1]], axis=-1)
    length = np.linalg.norm(g[:, edges[:, 0]] - g[:, edges[:, 1]], axis=-1)  # (T, E)
    return np.abs(length / rest - 1.0), edges


def quality(
    garment_vertices: np.ndarray,
    template: GarmentTemplate,
    body_vertices: np.ndarray,
    body_faces: np.ndarray,
    fps: float = 30.0,
    tolerance: float = PENETRATION_TOLERANCE,
) -> dict:
    """Per-frame plausibility numbers of a garment sequence on a body sequence.

    Args:
        garment_vertices: (T, V, 3) garment positions.
        template: the garment's rest shape (edge rest lengths) and faces.
        body_vertices: (T, Vb, 3) posed body, the same frames.
        body_faces: (Fb, 3) triangles of the closed body mesh, or a tuple of such meshes
            on the same vertices (the body without its arms and the arms, as the simulation
            collides with them): inside one of them is inside.
        fps: frame rate, for speeds.
        tolerance: metres; a vertex less deep inside the body than this touches it
            rather than penetrates (see below).

    Returns:
        A dict: ``inside_fraction`` (T,) fraction of garment vertices inside the
        body per frame, its ``inside_max`` and ``inside_mean``, and
        ``inside_depth_max`` (m), the deepest of those vertices;
        ``penetration_fraction`` (T,) and its ``penetration_max``: the fraction of
        vertices deeper inside than ``tolerance``. (The posed body folds into
        itself by millimetres where the skin creases, at the small of the back
        or under a forearm resting on the hip; cloth pressed into such a crease
        is inside by the winding number but not visibly through the skin.)
        ``strain_p50``,
        ``strain_p95``, ``strain_p99``, ``strain_max`` percentiles of
        ``|length / rest_length - 1|`` over all edges and frames (but those along
        the waistband, whose length the body sets); ``max_speed``
        (m/s) of any vertex between consecutive frames; ``nan_count``, the number
        of non-finite vertex positions. NaN vertices are left out of the others.
    """
    g = np.asarray(garment_vertices, np.float32)
    b = np.asarray(body_vertices, np.float32)
    V = template.num_vertices
    if g.ndim != 3 or g.shape[1:] != (V, 3):
        raise LoosefitInputError(
            "quality", "garment_vertices", f"shape (T, {V}, 3)", f"shape {g.shape}"
        )
    if b.ndim != 3 or b.shape[0] != g.shape[0] or b.shape[2] != 3:
        raise LoosefitInputError(
            "quality", "body_vertices", f"shape ({g.shape[0]}, Vb, 3)", f"shape {b.shape}"
        )
    finite = np.isfinite(g).all(-1)  # (T, V)
    inside = np.zeros(g.shape[0])
    deep = np.zeros(g.shape[0])
    depth = 0.0
    meshes = tuple(body_faces) if isinstance(body_faces, tuple | list) else (body_faces,)
    for t in range(g.shape[0]):
        within = np.zeros(V, bool)
        dist = np.zeros(V)  # the depth inside whichever mesh holds a vertex deepest
        for faces in meshes:
            hit = closest_points(b[t], faces, np.where(finite[t, :, None], g[t], 0.0))
            ins = hit.inside & finite[t]
            dist = np.where(ins, np.maximum(dist, hit.distance), dist)
            within |= ins
        inside[t] = within.mean()
        deep[t] = (within & (dist > tolerance)).mean()
        if within.any():
            depth = max(depth, float(dist[within].max()))
    strain, edges = edge_strain(g, template)
    strain = strain[finite[:, edges[:, 0]] & finite[:, edges[:, 1]]]
    p50, p95, p99 = np.percentile(strain, [50, 95, 99]) if strain.size else (np.nan,) * 3
    if g.shape[0] > 1:
        speed = np.linalg.norm(np.diff(g, axis=0), axis=-1) * fps  # (T - 1, V)
        speed = speed[finite[1:] & finite[:-1]]
    else:
        speed = np.zeros(0)
    return {
        "inside_fraction": inside,
        "inside_max": float(inside.max()),
        "inside_mean": float(inside.mean()),
        "inside_depth_max": depth,
        "penetration_fraction": deep,
        "penetration_max": float(deep.max()),
        "strain_p50": float(p50),
        "strain_p95": float(p95),
        "strain_p99": float(p99),
        "strain_max": float(strain.max()) if strain.size else float("nan"),
        "max_speed": float(speed.max()) if speed.size else 0.0,
        "nan_count": int((~finite).sum()),
    }
