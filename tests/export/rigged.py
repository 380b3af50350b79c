"""A small dressed animation built in code: a garment grid with UVs and a skinned body."""

from __future__ import annotations

import numpy as np

from loosefit.export import AnimatedMesh, Skin
from loosefit.geometry.rotations import axis_angle_to_matrix
from tests.meshes import grid


def _pose(R: np.ndarray, t) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = R, t
    return m


def rigged_body(T: int = 5) -> tuple[np.ndarray, np.ndarray, Skin]:
    """A 3-joint chain (root, bend, tip) skinning a 6 x 6 grid standing up.

    Returns:
        faces (F, 3), vertices (T, Vb, 3) and the rig that makes them.
    """
    v, f = grid(6, -0.3, 0.3)
    rest = np.stack([v[:, 0], 0.05 * v[:, 1], v[:, 1] + 1.0], 1)  # upright, 0.7 to 1.3 m
    heads = np.array([[0.0, 0.0, 0.7], [0.0, 0.0, 1.0], [0.0, 0.0, 1.2]])
    bind = np.stack([_pose(np.eye(3), h) for h in heads])  # (3, 4, 4) world
    d = rest[:, 2:3] - heads[:, 2][None]  # (Vb, 3) height over each joint
    weights = np.exp(-(d**2) / 0.02) + 1e-3
    weights = weights / weights.sum(1, keepdims=True)
    indices = np.broadcast_to(np.arange(3), weights.shape).copy()
    poses = np.empty((T, 3, 4, 4))
    for t in range(T):
        a = 0.3 * t / max(T - 1, 1)
        local = [
            _pose(axis_angle_to_matrix(np.array([0.0, 0.0, a])), [0.1 * t, 0.02 * t, 0.7]),
            _pose(axis_angle_to_matrix(np.array([a, 0.0, 0.0])), [0.0, 0.0, 0.3]),
            _pose(axis_angle_to_matrix(np.array([0.0, -a, 0.2 * a])), [0.0, 0.0, 0.2]),
        ]
        poses[t, 0] = local[0]
        poses[t, 1] = poses[t, 0] @ local[1]
        poses[t, 2] = poses[t, 1] @ local[2]
    skin = Skin(
        ("Hips", "Spine", "Neck"), np.array([-1, 0, 1]), rest, bind, weights, indices, poses
    )
    return f, skin.skinned().astype(np.float32), skin


def dressed(T: int = 5, skinned: bool = True) -> list[AnimatedMesh]:
    """The garment (a waving grid with UVs and a seam) and the rigged body."""
    v, f = grid(5, -0.2, 0.2, 0.9)
    t = np.arange(T, dtype=np.float32)[:, None, None]
    wave = 0.02 * np.sin(t + v[None, :, :1] * 10)
    garment = v[None] + t * np.float32([0.01, 0.0, -0.02]) + wave * np.float32([0, 1, 0])
    uvs = (v[:, :2] + 0.2) / 0.4
    uvs = np.concatenate([uvs, uvs[:5] + np.float32([0.5, 0.0])])  # a seam on the first row:
    odd = (np.arange(len(f)) % 2 == 0)[:, None]  # every other face there takes the copies
    face_uvs = np.where((f < 5) & odd, f + len(v), f)
    body_f, body_v, skin = rigged_body(T)
    return [
        AnimatedMesh("garment", f, garment, uvs, face_uvs, normals=True),
        AnimatedMesh("body", body_f, body_v, skin=skin if skinned else None),
    ]
