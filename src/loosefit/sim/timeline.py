"""A clip's body over the simulation's timeline (settle, blend, motion), what the cloth
collides with, and how finely each frame is stepped."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import torch

from loosefit.motion.chain import preroll
from loosefit.sim.cloth_config import ClothConfig

if TYPE_CHECKING:
    from loosefit.body.avatar import Avatar
    from loosefit.body.regions import BodyParts
    from loosefit.types import Motion


def substep_schedule(
    waist: np.ndarray,
    substeps: int,
    max_substeps: int,
    max_move: float,
    widen: int = 2,
    body_moves: np.ndarray | None = None,
    *,
    max_body_move: float | None = None,
) -> np.ndarray:
    """Substeps per frame, so that the waistband moves at most ``max_move`` per substep
    (and the body where the cloth can meet it at most ``max_body_move``, where given).

    A frame gets ``ceil(d / max_move)`` substeps, clipped to ``[substeps, max_substeps]``,
    where ``d`` is the largest move of a waistband point over that frame and the ``widen``
    frames on either side (so that a fast turn is entered and left with the finer step).

    Args:
        waist: (T, W, 3) the glued waistband points at each frame.
        substeps: the least substeps of a frame.
        max_substeps: the most.
        max_move: metres a waistband point may move in one substep.
        widen: frames on each side whose moves also count.
        body_moves: (T - 1,) m, the largest move of the body at the garment's height over
            each frame (:func:`body_moves`); with ``max_body_move``, a frame also gets
            ``ceil(body_moves / max_body_move)`` substeps (widened as the waist's).
        max_body_move: metres the body there may move in one substep; None: not counted.

    Returns:
        (T - 1,) int64: the substeps of the step from frame ``t`` to ``t + 1``.
    """
    waist = np.asarray(waist, np.float64)
    moves = np.linalg.norm(np.diff(waist, axis=0), axis=-1).max(-1)  # (T - 1,)
    if max_body_move is not None and body_moves is not None:
        # in units of the waist's move: the larger of the two demands
        moves = np.maximum(moves, np.asarray(body_moves, np.float64) * (max_move / max_body_move))
    if len(moves) and widen > 0:
        padded = np.pad(moves, widen, mode="edge")
        windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * widen + 1)
        moves = windows.max(-1)
    wanted = np.ceil(moves / max_move - 1e-9)
    return np.clip(wanted, substeps, max_substeps).astype(np.int64)


def body_moves(collider: np.ndarray, waist: np.ndarray, margin: float = 0.05) -> np.ndarray:
    """(T - 1,) m, the largest move over each frame of a collider vertex at the garment's
    height: below the waistband's highest point plus ``margin`` at the frame's start or end
    (the legs, the hips, a hand brought down to the skirt), where cloth can meet it.

    Args:
        collider: (T, Vb, 3) the body the cloth collides with, per frame.
        waist: (T, W, 3) the glued waistband points per frame.
    """
    top = np.asarray(waist, np.float64)[..., 2].max(-1) + margin  # (T,)
    low = np.minimum(collider[:-1, :, 2] - top[:-1, None], collider[1:, :, 2] - top[1:, None]) < 0
    move = np.linalg.norm(np.diff(collider, axis=0), axis=-1)  # (T - 1, Vb)
    return np.where(low, move, 0.0).max(-1, initial=0.0)


def limb_collider_faces(avatar: Avatar, config: ClothConfig) -> np.ndarray | None:
    """(Fl, 3) the arms' own collider (``config.arm_friction``), or None."""
    if config.arm_friction is None or config.arm_collision is True:
        return None
    return avatar.cut_limb_faces(config.arm_collision).cpu().numpy()


@dataclass
class Timeline:
    """A clip's body over the simulation's timeline: settle, blend, then the motion.

    Attributes:
        body: (P + T, Vb, 3) float32 the posed body (what every measure takes).
        collider: (P + T, Vb, 3) float32 what the cloth collides with: the posed body, its
            limbs pressed out of the rest of it where the pose folds into itself
            (``ClothConfig.flatten_overlaps``; else ``body`` itself).
        pressed: (P + T,) int64 collider vertices pressed per frame.
        overlap: (P + T,) m, the deepest limb vertex inside the rest of the body per frame.
        n_settle: frames of settling (the first frames of the preroll).
        n_pre: P, frames before the motion's first (settle and blend).
        root_pose: (4, 4) float64 the root joint's transform in the first frame.
    """

    body: np.ndarray
    collider: np.ndarray
    pressed: np.ndarray
    overlap: np.ndarray
    n_settle: int
    n_pre: int
    root_pose: np.ndarray


def timeline(
    avatar: Avatar, motion: Motion, config: ClothConfig, parts: BodyParts | None = None
) -> Timeline:
    """The body a clip's simulation meets, frame by frame (:class:`Timeline`); ``parts``:
    the avatar's :func:`~loosefit.body.regions.body_parts` with the config's arms
    (built here when needed and not given)."""
    pre_rot, pre_root, n_settle = preroll(
        motion,
        avatar.floor_height,
        config.settle_seconds,
        config.blend_seconds,
        config.settle_at_start,
    )
    rotations = torch.from_numpy(np.concatenate([pre_rot, motion.rotations]))
    root = torch.from_numpy(np.concatenate([pre_root, motion.root_translation]))
    with torch.no_grad():
        posed = avatar.pose(rotations, root)
    body = posed.vertices.detach().to("cpu", torch.float32).numpy()  # (P + T, Vb, 3)
    root_pose = posed.joint_transforms[0, 0].detach().double().cpu().numpy()  # (4, 4)
    collider, pressed, overlap = body, np.zeros(len(body), np.int64), np.zeros(len(body))
    if config.flatten_overlaps:
        from loosefit.sim.overlap import flatten_overlaps

        flat = flatten_overlaps(
            body, parts or collider_parts(avatar, config), config.overlap_inset, config.device
        )
        collider, pressed, overlap = flat.vertices, flat.moved, flat.depth
    return Timeline(body, collider, pressed, overlap, n_settle, len(pre_rot), root_pose)


def collider_parts(avatar: Avatar, config: ClothConfig) -> BodyParts:
    """The avatar's :class:`~loosefit.body.regions.BodyParts` with the arms the cloth
    meets (what the pressing of overlaps and the release of trapped cloth take)."""
    from loosefit.body.regions import body_parts

    return body_parts(avatar, arms=config.colliding_arms)


def collider_meshes(
    avatar: Avatar, config: ClothConfig
) -> tuple[np.ndarray, np.ndarray | None, tuple[np.ndarray, ...]]:
    """The body's collider faces (F, 3), the arms' own mesh (F', 3) where they collide as
    one (else None), and both as the tuple of closed meshes the cloth meets."""
    body_faces = avatar.collider_faces(arms=config.arm_collision).cpu().numpy()
    limb_faces = limb_collider_faces(avatar, config)
    meshes = (body_faces,) if limb_faces is None else (body_faces, limb_faces)
    return body_faces, limb_faces, meshes
