"""A contact sheet of a retargeted motion: the capture's skeleton beside the avatar.

For ``loosefit inspect-motion FILE --sheet sheet.png``: at a few frames, the source
skeleton drawn as thin sticks (its joints' forward kinematics, in the avatar's axes
and scale) to the left of the avatar's body posed by the retargeted motion, both on
the floor, one picture a frame, framed on that frame.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from loosefit.render.renderer import RenderConfig, Renderer, RenderMesh
from loosefit.render.video import contact_sheet


def bone_sticks(
    points: np.ndarray, bones: Sequence[tuple[int, int]], radius: float = 0.012, sides: int = 6
) -> tuple[np.ndarray, np.ndarray]:
    """Thin closed prisms along bones: a skeleton drawn as lines.

    Args:
        points: (K, P, 3) joint (and End Site) positions at K frames, metres.
        bones: pairs (a, b) of point indices, one stick each.
        radius: the sticks' radius, metres.
        sides: faces around each stick.

    Returns:
        faces (F, 3) int64 and vertices (K, V, 3) float32, V = 2 * sides * len(bones).
    """
    points = np.asarray(points, dtype=np.float64)
    K = points.shape[0]
    angle = 2 * np.pi * np.arange(sides) / sides
    verts, faces = [], []
    for i, (a, b) in enumerate(bones):
        p, q = points[:, a], points[:, b]  # (K, 3)
        d = q - p
        d = d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-9)
        helper = np.where(np.abs(d[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
        u = np.cross(d, helper)
        u /= np.maximum(np.linalg.norm(u, axis=-1, keepdims=True), 1e-9)
        w = np.cross(d, u)
        ring = radius * (
            np.cos(angle)[None, :, None] * u[:, None] + np.sin(angle)[None, :, None] * w[:, None]
        )  # (K, sides, 3)
        verts.append(np.concatenate([p[:, None] + ring, q[:, None] + ring], axis=1))
        o = 2 * sides * i
        for s in range(sides):
            t = (s + 1) % sides
            faces += [(o + s, o + t, o + sides + t), (o + s, o + sides + t, o + sides + s)]
        for s in range(1, sides - 1):  # the two caps
            faces += [(o, o + s + 1, o + s), (o + sides, o + sides + s, o + sides + s + 1)]
    vertices = np.concatenate(verts, axis=1) if verts else np.zeros((K, 0, 3))
    return np.asarray(faces, dtype=np.int64).reshape(-1, 3), vertices.astype(np.float32)


def skeleton_sheet(
    source_points: np.ndarray,
    bones: Sequence[tuple[int, int]],
    body_vertices: np.ndarray,
    body_faces: np.ndarray,
    frames: Sequence[int],
    size: int = 360,
    *,
    cols: int = 3,
    gap: float = 0.9,
) -> np.ndarray:
    """The capture's skeleton (sticks, left) beside the avatar (right) at K frames.

    Args:
        source_points: (K, P, 3) the source's joints and End Sites, avatar axes and scale,
            placed where the avatar dances (its root over the avatar's).
        bones: (a, b) pairs of ``source_points`` indices.
        body_vertices: (K, Vb, 3) the avatar's posed body at those frames.
        body_faces: (Fb, 3) its triangles.
        frames: the K frame numbers, for the captions.
        size: pixels of each picture's height (its width is 1.5 times that).
        cols: pictures a row.
        gap: metres the skeleton stands to the left of the avatar.

    Returns:
        (H, W, 3) uint8 sheet.
    """
    faces, sticks = bone_sticks(source_points, bones)
    shift = np.array([-gap, 0.0, 0.0], np.float32)
    config = RenderConfig(
        width=int(size * 1.5),
        height=size,
        views=("front",),
        labels=False,
        frame_counter=False,
        shadow_map_size=1024,
    )
    images, labels = [], []
    with Renderer(config) as renderer:
        for k, frame in enumerate(frames):
            scene = [
                RenderMesh(faces, sticks[k] + shift, "other", name="capture"),
                RenderMesh(body_faces, body_vertices[k], "body", name="avatar"),
            ]
            images.append(renderer.render_frame(scene, "front"))
            labels.append(f"frame {frame}: capture | avatar")
    return contact_sheet(images, cols=min(cols, len(images)), labels=labels)
