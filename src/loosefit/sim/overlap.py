"""A body pose that folds into itself, made a body the cloth can lie outside of.

The skinned body has no flesh that yields: in a deep crouch anny's thigh passes
centimetres into the belly (60_02's lunge: 3.5 cm), its surface crossing the belly's.
The simulation's collider is that one mesh, and Newton decides inside from outside by
ray parity, which calls the lens where the two volumes overlap *outside* (two surfaces
crossed): the cloth the thigh folds against the belly is held there, in the lens, and
ends up centimetres inside the body by any other measure (the winding number, the eye).
``loosefit diagnose`` finds this as the cause of every deep event of the salsa clips.

:func:`flatten_overlaps` gives the collider what soft tissue would do: each limb's
vertices that are inside the rest of the body are pressed back onto the rest's surface
(``inset`` short of it, so that no sliver of lens is left), as flesh pressed against
flesh. The union of the two volumes is unchanged (what was pressed lay inside the rest
anyway), so cloth kept outside the flattened collider is outside the posed body too,
and nothing moves while the limbs are clear of each other. Only the collider changes:
the motion, the body a data set records and every measure stay the posed body.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from loosefit.body.regions import BodyParts
from loosefit.geometry.query import Surface


@dataclass
class Flattened:
    """What :func:`flatten_overlaps` did.

    Attributes:
        vertices: (T, Vb, 3) the collider's body, limbs pressed out of the rest.
        moved: (T,) int64 body vertices moved in each frame.
        depth: (T,) metres: the deepest limb vertex inside the rest of the body per frame.
    """

    vertices: np.ndarray
    moved: np.ndarray
    depth: np.ndarray


def flatten_overlaps(
    body: np.ndarray, parts: BodyParts, inset: float = 0.002, device: str = "cpu"
) -> Flattened:
    """Press every colliding limb's vertices that lie inside the rest of the body onto it.

    Args:
        body: (T, Vb, 3) posed body vertices.
        parts: the body's limbs and, for each, the closed rest of the collider without it
            (:func:`~loosefit.body.regions.body_parts` with the simulation's arms).
        inset: metres; a pressed vertex stops this far inside the rest's surface
            (negative: this far outside it).
        device: warp device of the closest-point queries ("cpu", "cuda:0": a simulation
            on a GPU keeps this CPU work off its critical path).

    Returns:
        The :class:`Flattened` body: a vertex less deep than ``inset`` is left where it
        is; frames with no limb inside the rest are returned unchanged.
    """
    body = np.asarray(body, np.float32)
    out = body.copy()
    T = len(body)
    moved = np.zeros(T, np.int64)
    depth = np.zeros(T)
    limbs = [limb for limb in parts.limb_vertices if parts.limb_collides[limb]]
    surfaces = {limb: Surface(body[0], parts.limb_faces[limb], device) for limb in limbs}
    tested = {limb: parts.tested_vertices(limb)[0] for limb in limbs}
    hints: dict[str, np.ndarray] = {}  # each limb's closest faces last frame: found sooner
    for t in range(T):
        for limb in limbs:  # in order: a limb meets the others as already pressed
            surface = surfaces[limb]
            surface.refit(out[t])
            hit = surface.query(out[t, tested[limb]], hint=hints.get(limb))
            hints[limb] = hit.faces
            buried = hit.inside & (hit.faces >= 0)
            if not buried.any():
                continue
            d = hit.distance[buried]
            depth[t] = max(depth[t], float(d.max()))
            deep = d > max(inset, 1e-9)  # (a negative inset also moves the shallowest)
            if not deep.any():
                continue
            idx = tested[limb][buried][deep]
            v, p, dd = out[t, idx], hit.points[buried][deep], d[deep, None]
            out[t, idx] = v + (p - v) * ((dd - inset) / dd)
            moved[t] += len(idx)
    return Flattened(out, moved, depth)
