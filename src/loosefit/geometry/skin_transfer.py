"""Skinning weights for a garment, taken from the body it is worn on (Santesteban et al. 2019).

A garment vertex near the body takes the weights of its closest point on the
body's surface (the barycentric blend of that face's vertex weights). A vertex
far from the body (a loose skirt's hem, well away from the legs) would take
the weights of whatever body part happens to be nearest, so its weights are
instead *diffused* over the garment from the near ones: they are the harmonic
interpolation (uniform graph Laplacian, Dirichlet values at the near vertices),
a convex blend of the near vertices' weights, smooth over the cloth. A part of
the garment with no near vertex at all keeps its closest-point weights.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from loosefit.errors import LoosefitInputError
from loosefit.geometry.edges import unique_edges
from loosefit.geometry.query import closest_points


def closest_point_weights(
    garment: np.ndarray, body: np.ndarray, body_faces: np.ndarray, body_weights: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Each garment vertex's closest point on the body, and that point's blended weights.

    Args:
        garment: (V, 3) garment vertices at the body's rest pose.
        body: (Vb, 3) body vertices at the rest pose; ``body_faces`` (F, 3) its triangles.
        body_weights: (Vb, J) dense skinning weights of the body's vertices.

    Returns:
        weights (V, J) and the distance (V,) of each garment vertex to the body.
    """
    hit = closest_points(body, body_faces, garment)
    corners = np.asarray(body_faces)[hit.faces]  # (V, 3)
    w = (hit.barycentric[..., None] * np.asarray(body_weights)[corners]).sum(1)  # (V, J)
    return w, hit.distance


def diffuse_weights(weights: np.ndarray, faces: np.ndarray, known: np.ndarray) -> np.ndarray:
    """Harmonic interpolation of per-vertex weights from the ``known`` vertices.

    Args:
        weights: (V, J) weights; the rows of ``known`` vertices are kept.
        faces: (F, 3) the garment's triangles (their edges define the graph).
        known: (V,) bool, the Dirichlet vertices.

    Returns:
        (V, J) weights: ``known`` rows unchanged; every other vertex connected to a
        known one the average of its neighbours (``L_uu W_u = -L_uk W_k``); vertices
        in a part with no known vertex keep their rows. Rows are renormalised to 1.
    """
    V = len(weights)
    known = np.asarray(known, bool)
    if known.shape != (V,):
        raise LoosefitInputError("diffuse_weights", "known", f"shape ({V},)", f"{known.shape}")
    e, _ = unique_edges(np.asarray(faces))
    adj = sp.coo_matrix(
        (np.ones(2 * len(e)), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])), shape=(V, V)
    ).tocsr()
    n_comp, label = sp.csgraph.connected_components(adj, directed=False)
    anchored = np.zeros(n_comp, bool)
    anchored[np.unique(label[known])] = True
    free = ~known & anchored[label]
    out = np.array(weights, np.float64)
    if free.any():
        lap = sp.diags(np.asarray(adj.sum(1)).ravel()) - adj
        lu = lap[free][:, free].tocsc()
        rhs = -(lap[free][:, known] @ out[known])
        out[free] = spla.splu(lu).solve(np.asarray(rhs))
    out = np.clip(out, 0.0, None)
    return out / out.sum(1, keepdims=True)


def garment_skin_weights(
    garment: np.ndarray,
    garment_faces: np.ndarray,
    body: np.ndarray,
    body_faces: np.ndarray,
    body_weights: np.ndarray,
    near: float = 0.02,
) -> np.ndarray:
    """Skinning weights of a garment from the body (closest point, diffused where far).

    Args:
        garment: (V, 3) garment vertices on the body at its rest pose.
        garment_faces: (F, 3) the garment's triangles.
        body: (Vb, 3) body rest vertices; ``body_faces`` (Fb, 3) its triangles.
        body_weights: (Vb, J) dense skinning weights of the body.
        near: metres; vertices at most this far from the body keep their
            closest-point weights, the others get diffused ones.

    Returns:
        (V, J) float32 weights, rows summing to 1.

    Raises:
        LoosefitInputError: no garment vertex within ``near`` of the body.
    """
    w, distance = closest_point_weights(garment, body, body_faces, body_weights)
    known = distance <= near
    if not known.any():
        raise LoosefitInputError(
            "garment_skin_weights",
            "garment",
            f"a vertex within {near} m of the body (the garment worn at the body's rest pose)",
            f"the nearest {float(distance.min()):.3f} m away",
        )
    return diffuse_weights(w, garment_faces, known).astype(np.float32)
