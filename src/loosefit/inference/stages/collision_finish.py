"""Collision handling beyond the paper's solve (Eq. 16), for
:class:`~loosefit.inference.stages.collision.CollisionHandler`: each step reads the
handler's configuration and operators and asks the body through its hinted queries.

* :func:`last_projection` (``finish``): the vertices the winding number puts inside the
  body (where body parts overlap the closest face's side misleads the solve) moved out,
  never farther than ``finish_limit``;
* :func:`mend_tears` (``relax``): edges stretched past ``stretch`` times their rest length
  by pushes out of two body parts pressed together, shortened and projected out again;
* :func:`sticky_side` (``sticky``): cloth inside a limb leaves it on the side it left by
  in the frame before.

Why each exists and the figures behind its defaults: docs/design/notes/collision.md.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from loosefit.geometry.query import ClosestPoints, Surface
from loosefit.geometry.signed_distance import beyond_skin, hit_distances, on_skin

if TYPE_CHECKING:
    from loosefit.inference.stages.collision import CollisionHandler


class Finished(NamedTuple):
    """The garment after one of these steps."""

    vertices: np.ndarray  # (V, 3) the garment
    distances: np.ndarray  # (V,) signed distances to the body, negative inside, m
    queries: int  # the body queries made


def last_projection(
    handler: CollisionHandler, x: np.ndarray, ds: np.ndarray, body: Surface
) -> Finished:
    """``finish``: every vertex near the body that the winding number puts
    inside it (a crease, two body parts pressed together, an arm in the torso, where
    the closest face's side misleads the solve) moved straight to ``eps`` beyond its
    closest skin, then asked again, ``finish`` times at most. A vertex still inside
    after its projection (it sat on an inner skin, the arm's surface inside the torso,
    or was caught where two body parts overlap, each projection sending it into the
    other) goes on the way it went to the next skin that way meets (a ray), ``eps``
    beyond it, but never farther than ``finish_limit`` from where the solve left it: one
    not out by then stays inside (pinched between body parts). A vertex lying on the
    outside of its closest skin (within ``face_reach``) that is inside all the same is
    in another body part pressed onto that skin (a forearm on the hip): the cloth is
    pinched there, and stays (walked on, it would come out a body part's width away in
    one frame and not the next: docs/design/notes/collision.md). The edges its moves
    stretch are mended by :func:`mend_tears`.

    Args:
        handler: the garment's operators and the configuration.
        x: (V, 3) the garment after the solves; ds: (V,) their signed distances.
        body: the posed body's surface.

    Returns:
        :class:`Finished`: the garment, its signed distances (negative inside, by the
        winding number where asked again) and the queries made.
    """
    cfg = handler.config
    start, x, ds = x, x.copy(), ds.copy()  # start: where the solve left them
    near = np.flatnonzero(ds < cfg.finish_reach)  # inside or near, as the solve saw it
    passes = 0
    went = np.zeros_like(x)  # (V, 3) the direction each vertex was last moved in

    def ask(near: np.ndarray, known: bool = False):
        """The winding number's answer for the vertices ``near``, into ``ds``; ``known``:
        their closest points are the solve's last answers, at the same positions (the
        fast path's first round: only the rays are cast)."""
        if known:
            points, faces = handler._closest[near], handler._face[near]
            inside = body.inside_by_rays(x[near], points, faces)
            hit = ClosestPoints(
                points,
                faces,
                np.zeros_like(points),
                inside,
                np.linalg.norm(points - x[near].astype(np.float32), axis=1),
            )
        else:
            hit = handler._ask(x[near], body, near, handler.inside_test)
        ds[near] = hit_distances(hit)
        return hit, (hit.faces >= 0) & hit.inside

    for k in range(cfg.finish):
        if not len(near):
            break
        hit, inside = ask(near, known=cfg.fast and k == 0)
        passes += 1
        if not inside.any():
            break
        idx = near[inside]
        beyond, out = beyond_skin(x[idx], hit, inside, cfg.epsilon, body)
        # moved before and still inside: on an inner skin, or caught between two body
        # parts that a projection only swaps: it goes on the way it went, as far as the
        # limit lets it (those at the limit stay, and are not asked again)
        on_inner = went[idx].any(1)
        step = beyond  # (K, 3) where each goes this round
        # (K,) not moved yet, on the outside of its closest skin: pinched, stays
        stuck = ~on_inner & on_skin(x[idx], body, hit, inside, cfg.face_reach)
        step[stuck] = x[idx[stuck]]
        if on_inner.any():  # on to the next skin its way meets, eps beyond
            w = idx[on_inner]
            left = cfg.finish_limit - np.linalg.norm(x[w] - start[w], axis=1)  # (Kw,)
            t, face = body.first_hits(x[w], went[w], float(max(left.max(), 0.0)))
            go = (face >= 0) & (t + cfg.epsilon <= left)
            step[on_inner] = np.where(
                go[:, None], x[w] + (t + cfg.epsilon)[:, None] * went[w], x[w]
            )
            stuck[on_inner] = ~go
        x[idx] = step
        went[idx] = np.where(on_inner[:, None], went[idx], out)
        near = idx[~stuck]  # only these can still be inside (the others did not move)
    else:  # the passes ran out with vertices just moved: where they are now, reported
        if cfg.finish and len(near):
            ask(near)
            passes += 1
    return Finished(x, ds, passes)


def mend_tears(
    handler: CollisionHandler, x0: np.ndarray, x: np.ndarray, ds: np.ndarray, body: Surface
) -> Finished:
    """``relax``: pushes out along the normals of two body parts pressed together (a
    hand on the hip, a thigh on the belly in a crouch) send neighbouring vertices to
    either side and stretch the edge between to many times its length. Every edge
    longer than ``stretch`` times its rest length (and than it was in ``x0``) is
    shortened to that, its two vertices moving alike (averaged over their edges), and
    the vertices moved are then projected out of the body again (to ``eps`` beyond the
    closest skin, where the winding number, or the closest face's side without the last
    projection, puts them inside); ``relax`` rounds. The projection is last, so no vertex
    it asks about is left inside; where two body parts press together the tear is
    mended only in part (the figures, and why the projection comes last:
    docs/design/notes/collision.md).

    Args:
        handler: the garment's operators and the configuration.
        x0: (V, 3) the garment before collision handling; x: (V, 3) after the solve and
            the last projection; ds: (V,) its signed distances.
        body: the posed body's surface.

    Returns:
        :class:`Finished`: the garment, its signed distances (asked again where moved) and
        the queries made.
    """
    cfg = handler.config
    x, ds = x.copy(), ds.copy()
    a, b = handler.edges[:, 0], handler.edges[:, 1]
    passes = 0
    stale = np.zeros(len(x), dtype=bool)  # (V,) moved since ``ds`` was asked for it
    sign = handler.inside_test if cfg.finish else "normal"
    for _ in range(cfg.relax):
        # only an edge with an end moved can be over its limit (the others are as long
        # as before, which the limit is at least): the same edges, a fraction of the work
        changed = (x != x0).any(1)  # (V,)
        maybe = np.flatnonzero(changed[a] | changed[b])
        before = np.linalg.norm(x0[a[maybe]] - x0[b[maybe]], axis=1)
        rest = before if handler.rest_lengths is None else handler.rest_lengths[maybe]
        limit = np.maximum(before, cfg.stretch * rest)  # (M,)
        vec = x[a[maybe]] - x[b[maybe]]
        length = np.linalg.norm(vec, axis=1)
        keep = length > limit
        over = maybe[keep]
        if not len(over):
            break
        vec, length = vec[keep], length[keep]
        corr = (0.5 * (length - limit[keep]) / length)[:, None] * vec
        ends = np.r_[a[over], b[over]]  # (2 O,) each over-long edge's two vertices
        pull = np.concatenate([-corr, corr])  # (2 O, 3) what each end takes
        delta = np.stack([np.bincount(ends, pull[:, k], len(x)) for k in range(3)], 1)
        count = np.bincount(ends, minlength=len(x))
        touched = np.flatnonzero(count)
        x[touched] += delta[touched] / count[touched, None]
        hit = handler._ask(x[touched], body, touched, sign)
        passes += 1
        ds[touched] = hit_distances(hit)
        stale[touched] = False
        inside = hit.inside & (hit.faces >= 0)
        if inside.any():
            idx = touched[inside]
            x[idx] = beyond_skin(x[idx], hit, inside, cfg.epsilon, body)[0]
            stale[idx] = True
    if stale.any():  # where the last projections left them (the others as asked)
        idx = np.flatnonzero(stale)
        hit = handler._ask(x[idx], body, idx, sign)
        passes += 1
        ds[idx] = hit_distances(hit)
    return Finished(x, ds, passes)


def sticky_side(
    handler: CollisionHandler,
    x: np.ndarray,
    n: np.ndarray,
    ds: np.ndarray,
    way: np.ndarray | None,
    body: Surface,
) -> tuple[np.ndarray, np.ndarray]:
    """``sticky``: the vertices at ``x`` (N, 3) inside the body (``ds < 0``) whose closest
    skin is now against the way they were moved out in the frame before (``way``, (N, 3)
    unit or 0) leave along that way instead, to where its ray first meets the skin, if
    that is at most ``sticky_factor`` times as far as the closest skin (plus
    ``sticky_slack``). ``handler``: the garment's operators and the configuration;
    ``n`` (N, 3), ``ds`` (N,): the normals and signed distances the closest skin gives.

    Returns:
        The normals ``n`` (N, 3) and signed distances ``ds`` (N,), theirs changed (in
        place; as given where ``way`` is None).
    """
    if way is None:
        return n, ds
    turn = np.flatnonzero((ds < 0) & ((n * way).sum(1) < 0))
    if not len(turn):
        return n, ds
    reach = -ds[turn] * handler.config.sticky_factor + handler.config.sticky_slack  # (K,)
    t, face = body.first_hits(x[turn], way[turn], float(reach.max()))
    ok = (face >= 0) & (t <= reach)
    n[turn[ok]] = way[turn[ok]]
    ds[turn[ok]] = -t[ok]
    return n, ds
