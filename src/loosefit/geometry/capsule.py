"""Capsules: the forward kinematics that places them, and the push-out of points from them.

Pure functions over batches, in torch (the engine tier's graph runs them:
:mod:`loosefit.inference.engine.export`); the capsules themselves are fitted in
:mod:`loosefit.body.capsules`.
"""

from __future__ import annotations

import torch


def chain_frames(
    rotations: torch.Tensor,
    root: torch.Tensor,
    parents: list[int],
    offsets: torch.Tensor,
    joints: list[int],
) -> torch.Tensor:
    """World frames of some joints, ``G_root = [R_root | root]``, ``G_j = G_parent
    T(offset_j) R_j`` (:func:`loosefit.body.capsules.joint_frames`, its numpy twin).

    Args:
        rotations: (B, J, 3, 3) local rotations.
        root: (B, 3) the root's world position.
        parents: J parent indices (-1 for the root), parents before children.
        offsets: (J, 3) each joint's head minus its parent's at rest.
        joints: the joints wanted.

    Returns:
        (B, len(joints), 3, 3) rotations and (B, len(joints), 3) positions.
    """
    need: set[int] = set()
    for j in joints:
        while j >= 0 and j not in need:
            need.add(j)
            j = parents[j]
    R: dict[int, torch.Tensor] = {}
    p: dict[int, torch.Tensor] = {}
    for j in sorted(need):
        if parents[j] < 0:
            R[j], p[j] = rotations[:, j], root
        else:
            q = parents[j]
            R[j] = R[q] @ rotations[:, j]
            p[j] = p[q] + R[q] @ offsets[j]
    return torch.stack([R[j] for j in joints], 1), torch.stack([p[j] for j in joints], 1)


DEEP = 0.25  # the share of the radius under which a point is pushed out partly (see push_out)


def push_out(
    x: torch.Tensor,
    start: torch.Tensor,
    end: torch.Tensor,
    radius: torch.Tensor,
    origin: torch.Tensor | None = None,
    weight: torch.Tensor | None = None,
) -> torch.Tensor:
    """Points pushed out of capsules: a point at distance ``n < r`` from a capsule's segment
    moves by ``r - n`` along the direction from the segment's nearest point (by
    ``(r - n) n / (DEEP r)`` where ``n < DEEP r``), the moves of every capsule it is inside
    summed (continuous in the points and the capsules: where two
    capsules overlap, a point inside both leaves both at once, about).

    Every distance comes from batched matrix products (``|x - a|^2 = |x|^2 - 2 x.a + |a|^2``,
    ``(x - a).(b - a)``) and the moves from two more, never a (B, N, C, 3) array.

    Args:
        x: (B, N, 3) points.
        start, end: (B, C, 3) the capsules' segments.
        radius: (C,) their radii.
        origin: (B, 3) a point near them all (the root), subtracted first for precision.
        weight: (N, C) the share of each capsule's move each point makes (0: held where it
            is; None: 1).

    Returns:
        (B, N, 3) the points, moved where inside.
    """
    if origin is not None:
        o = origin[:, None]
        return push_out(x - o, start - o, end - o, radius, weight=weight) + o
    ab = end - start  # (B, C, 3)
    L2 = (ab * ab).sum(-1).clamp_min(1e-12)[:, None]  # (B, 1, C)
    s = x @ ab.transpose(1, 2) - (start * ab).sum(-1)[:, None]  # (B, N, C): (x - a).ab
    t = (s / L2).clamp(0.0, 1.0)
    x2 = (x * x).sum(-1, keepdim=True)  # (B, N, 1)
    a2 = (start * start).sum(-1)[:, None]  # (B, 1, C)
    d2 = x2 - 2 * (x @ start.transpose(1, 2)) + a2 + t * (t * L2 - 2 * s)  # |x - a - t ab|^2
    n = d2.clamp_min(0.0).sqrt()  # (B, N, C)
    # the move over the distance; deeper than DEEP r, where the direction from the segment
    # turns fast (undefined on it), a point moves by its depth times n / (DEEP r) only:
    # bounded, continuous, and out within a few frames
    w = (radius - n).clamp_min(0.0) / torch.maximum(n, DEEP * radius)
    if weight is not None:
        w = w * weight  # (B, N, C)
    # sum_c w_c (x - a_c - t_c ab_c)
    return x + x * w.sum(-1, keepdim=True) - w @ start - (w * t) @ ab
