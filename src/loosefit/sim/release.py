"""The release of trapped cloth: vertices deep inside the body put back on the skin.

Cloth pinched between two body parts can sink past the contact's reach and stay inside
(``ClothConfig.release_depth``). :class:`TrappedRelease` puts it back after each frame;
:func:`replay_release` tells whether a recorded clip would have been changed by it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from loosefit.body.regions import BodyParts


class TrappedRelease:
    """Puts cloth vertices deep inside the body back on the skin where they went in.

    A vertex inside one of ``meshes`` farther than ``depth`` from its surface, after a
    frame, goes back to the spot of the body part it is in (the part of its closest face)
    over which it was last seen outside: its anchor on that part, the closest point of the
    part's skin then, carried along as the skin moves; ``offset`` out along that face's
    normal, with the skin's velocity there. Every vertex outside all meshes is anchored
    anew on each part. Cloth pinched into a part comes back on the side it went in from,
    next to its neighbours. Measured on ballet 05_16 (docs/use/DATASET.md), the closest
    surface point instead can lie on the far side of a thigh, and one anchor for the whole
    body can lie on the other thigh (the cloth was pressed between the two): a vertex put
    there pulls its neighbours through the legs (edge strain p99 13 and 30). A vertex never
    seen outside goes to the closest point.

    Args:
        body: (Vb, 3) the collider's body in the first frame.
        meshes: (F, 3) triangle arrays over the body's vertices, each a closed mesh.
        vertex_part: (Vb,) int64 the part of each body vertex (0 .. P - 1).
        num_vertices: V, cloth vertices.
        depth: metres inside a surface beyond which a vertex is released.
        offset: metres outside the surface it is put.

    Attributes:
        face: (V, P) int64 each vertex's anchor face on each part (-1: none yet), an index
            into ``patches[p]``.
        barycentric: (V, P, 3) float64 the anchor point in that face.
        patches: P (F_p, 3) the faces of each part (over all meshes).
    """

    def __init__(
        self,
        body: np.ndarray,
        meshes: tuple[np.ndarray, ...],
        vertex_part: np.ndarray,
        num_vertices: int,
        depth: float,
        offset: float,
    ) -> None:
        from loosefit.geometry.cap import triangle_keys
        from loosefit.geometry.query import Surface

        self.depth, self.offset = float(depth), float(offset)
        every = np.concatenate(meshes)
        first = np.unique(triangle_keys(every)[0], return_index=True)[1]
        faces = every[np.sort(first)]  # each triangle once, as first given
        c = np.asarray(vertex_part, np.int64)[faces]  # (F, 3) each corner's part
        # the part of most corners (of three different parts, the lowest)
        part = np.where(
            c[:, 1] == c[:, 2],
            c[:, 1],
            np.where((c[:, 0] == c[:, 1]) | (c[:, 0] == c[:, 2]), c[:, 0], c.min(1)),
        )
        P = int(np.asarray(vertex_part).max()) + 1
        self.patches = [faces[part == p] for p in range(P)]
        body = np.asarray(body, np.float32)
        self._whole = [Surface(body, f) for f in meshes]
        self._parts = [Surface(body, f) if len(f) else None for f in self.patches]
        self._part_of = [part[_rows_index(faces, f)] for f in meshes]  # mesh face -> part
        self.face = np.full((num_vertices, P), -1, np.int64)
        self.barycentric = np.zeros((num_vertices, P, 3))

    def step(
        self,
        positions: np.ndarray,
        velocities: np.ndarray,
        body: np.ndarray,
        body_before: np.ndarray,
        frame_dt: float,
    ) -> tuple[np.ndarray, np.ndarray, int]:
        """Release the deep vertices after a frame and anchor the ones outside.

        Args:
            positions: (V, 3) cloth vertices after the frame.
            velocities: (V, 3) their velocities.
            body: (Vb, 3) the collider's body at the end of the frame.
            body_before: (Vb, 3) at its start.
            frame_dt: seconds of the frame.

        Returns:
            The new (V, 3) positions and velocities (copies) and how many vertices moved.
        """
        x = np.array(positions, np.float32)
        v = np.array(velocities, np.float32)
        body = np.asarray(body, np.float32)
        for s in (*self._whole, *(p for p in self._parts if p is not None)):
            s.refit(body)
        n = len(x)
        inside = np.zeros(n, bool)
        deep_part = np.full(n, -1, np.int64)  # the part a deep vertex is in
        deep_dist = np.zeros(n)
        for hit, part_of in zip((s.query(x) for s in self._whole), self._part_of, strict=True):
            found = hit.faces >= 0
            inside |= hit.inside & found
            deep = hit.inside & found & (hit.distance > np.maximum(self.depth, deep_dist))
            deep_part[deep] = part_of[hit.faces[deep]]
            deep_dist[deep] = hit.distance[deep]
        where = np.flatnonzero(deep_part >= 0)
        for p in np.unique(deep_part[where]):
            idx = where[deep_part[where] == p]
            face, bary = self.face[idx, p], self.barycentric[idx, p]
            fresh = face < 0
            if fresh.any():  # never seen outside: the closest point of the part
                hit = self._parts[p].query(x[idx[fresh]])
                face[fresh], bary[fresh] = hit.faces, hit.barycentric
            tri = self.patches[p][face]  # (k, 3)
            a, b, c = (body[tri[:, i]] for i in range(3))
            normal = np.cross(b - a, c - a)
            normal /= np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-12)
            w = bary[:, :, None]  # (k, 3, 1)
            x[idx] = (body[tri] * w).sum(1) + self.offset * normal
            v[idx] = ((body[tri] - np.asarray(body_before, np.float32)[tri]) * w).sum(1) / frame_dt
        out = np.flatnonzero(~inside)
        if len(out):
            for p, s in enumerate(self._parts):
                if s is not None:
                    hit = s.query(x[out])
                    self.face[out, p], self.barycentric[out, p] = hit.faces, hit.barycentric
        return x, v, len(where)

    def state(self) -> dict[str, np.ndarray]:
        """The anchors, to save with a run."""
        return {"anchor_face": self.face.copy(), "anchor_barycentric": self.barycentric.copy()}

    def load(self, state: dict[str, np.ndarray]) -> None:
        """Take the anchors of :meth:`state`."""
        self.face = np.array(state["anchor_face"], np.int64)
        self.barycentric = np.array(state["anchor_barycentric"], np.float64)


def _rows_index(rows: np.ndarray, of: np.ndarray) -> np.ndarray:
    """(F',) index into ``rows`` (F, 3) of each triangle of ``of`` (F', 3), as sets."""
    from loosefit.geometry.cap import triangle_keys

    ka, kb = triangle_keys(rows, of)
    order = np.argsort(ka)
    return order[np.searchsorted(ka, kb, sorter=order)]


def release_parts(parts: BodyParts) -> np.ndarray:
    """(Vb,) int64 the body part of each body vertex for :class:`TrappedRelease`: 0 the
    trunk and head, then each limb of :data:`loosefit.body.regions.LIMBS`."""
    out = np.zeros(len(parts.region), np.int64)
    for i, verts in enumerate(parts.limb_vertices.values()):
        out[verts] = i + 1
    return out


def replay_release(
    garment: np.ndarray, collider: np.ndarray, release: TrappedRelease, frame_dt: float
) -> int:
    """Frames of a simulated clip the release of trapped cloth would have changed.

    ``release.step`` over the recorded frames in order, as the simulation runs it (from
    the motion's first frame): where it moves nothing, the clip is the one a run with the
    release on makes (the simulation is deterministic), and ``release`` holds that run's
    anchors after the last frame.

    Args:
        garment: (T, V, 3) the recorded cloth frames.
        collider: (T, Vb, 3) the collider's body in those frames.
        release: a fresh :class:`TrappedRelease` (its anchors are updated).
        frame_dt: seconds per frame.

    Returns:
        How many frames it would have moved cloth in.
    """
    fired = 0
    still = np.zeros(garment.shape[1:], np.float32)
    for t in range(len(garment)):
        fired += (
            release.step(garment[t], still, collider[t], collider[max(t - 1, 0)], frame_dt)[2] > 0
        )
    return fired
