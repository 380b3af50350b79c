"""A skeleton's clip as a motion file holds it (:class:`BvhClip`), and its kinematics.

The BVH reader (:mod:`loosefit.motion.bvh`) and the glTF reader (:mod:`loosefit.motion.gltf`)
both give a :class:`BvhClip`: the skeleton and its frames in the file's own axes, metres.
Here are the functions over it: world joint positions and rotations
(:func:`forward_kinematics`, ``G_j = G_parent @ [R_j | t_j]``), End Site positions, the rest
pose, and the body's joints and size at rest.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from loosefit.errors import LoosefitInputError


@dataclass
class BvhClip:
    """A BVH file's skeleton and motion, lengths in metres, in the file's own frame.

    Attributes:
        path: the file read.
        joint_names: J joint names in file order (parents before children);
            End Sites are not joints.
        parents: (J,) int64 parent indices, -1 for the root.
        offsets: (J, 3) float32 OFFSET of each joint from its parent, metres; a joint
            whose OFFSET is zero and whose position channels carry its bone (a rig whose
            shape exists only in its frames) has the channels' median over the frames.
        channels: per joint, the channel names in file order, e.g.
            ``("Zrotation", "Xrotation", "Yrotation")``.
        end_offsets: End Site offsets, metres, keyed by the index of the joint
            that carries the End Site: {j: (3,) float32}.
        rotations: (T, J, 3, 3) float32 local rotation matrices (identity for
            joints without rotation channels).
        local_translations: (T, J, 3) float32 translation of each joint in its
            parent's frame, metres: the offset combined with any position channels.
        frame_time: seconds per frame, as written in the file.
        units_scale: the factor that took the file's lengths to metres.
        meta: free-form notes for later stages; when read, ``bones_from_frames`` lists
            the joints whose offsets came from their position channels (if any).
    """

    path: Path
    joint_names: tuple[str, ...]
    parents: np.ndarray
    offsets: np.ndarray
    channels: list[tuple[str, ...]]
    end_offsets: dict[int, np.ndarray]
    rotations: np.ndarray
    local_translations: np.ndarray
    frame_time: float
    units_scale: float = 1.0
    meta: dict = field(default_factory=dict)

    @property
    def fps(self) -> float:
        """Frames per second, ``1 / frame_time`` (120.0048 for a written 0.008333)."""
        return 1.0 / self.frame_time

    @property
    def num_frames(self) -> int:
        return int(self.rotations.shape[0])

    @property
    def num_joints(self) -> int:
        return len(self.joint_names)

    @property
    def root_positions(self) -> np.ndarray:
        """(T, 3) float32 root joint position, metres, in the file's frame."""
        return self.local_translations[:, 0]

    def index(self, name: str) -> int:
        """Index of the joint called ``name``."""
        try:
            return self.joint_names.index(name)
        except ValueError:
            raise LoosefitInputError(
                self.path, "joint name", f"one of {list(self.joint_names)}", repr(name)
            ) from None


def body_joints(parents: np.ndarray) -> list[int]:
    """The joints of the body: the subtree of the first joint that branches (a root joint
    of no geometry of its own above the hips, and the joints on its way down, left out);
    every joint when none branches."""
    kids: dict[int, list[int]] = {}
    for j, p in enumerate(parents):
        kids.setdefault(int(p), []).append(j)
    top = kids.get(-1, [0])[0]
    while len(kids.get(top, [])) == 1:
        top = kids[top][0]
    if not kids.get(top):  # a chain: no joint branches, all of it is the body
        return list(range(len(parents)))
    body, stack = [], [top]
    while stack:
        j = stack.pop()
        body.append(j)
        stack += kids.get(j, [])
    return sorted(body)


def body_extent(parents: np.ndarray, offsets: np.ndarray, end_offsets: dict) -> float:
    """The largest side of the body's bounding box at rest (:func:`body_joints` and their
    End Sites), in the offsets' unit.

    Args:
        parents: (J,) parent indices; offsets: (J, 3) OFFSETs; end_offsets: {j: (3,)}.
    """
    rest = _rest_positions(parents, offsets)
    body = body_joints(parents)
    points = [rest[body]] + [rest[j] + np.asarray(o) for j, o in end_offsets.items() if j in body]
    points = np.vstack(points)
    return float((points.max(0) - points.min(0)).max())


def forward_kinematics_arrays(
    parents: np.ndarray, rotations: np.ndarray, translations: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """World joint positions and rotations of a kinematic tree.

    ``G_j = G_parent(j) @ [rotations_j | translations_j]``, root: ``[R_0 | t_0]``.

    Args:
        parents: (J,) parent indices, -1 for roots; every parent precedes its children.
        rotations: (T, J, 3, 3) local rotations.
        translations: (T, J, 3) or (J, 3) local translations (offset from the parent).

    Returns:
        positions: (T, J, 3) float32 world joint positions.
        world_rotations: (T, J, 3, 3) float32 world rotations.
    """
    rot = np.asarray(rotations, dtype=np.float64)
    T, J = rot.shape[:2]
    trans = np.broadcast_to(np.asarray(translations, dtype=np.float64), (T, J, 3))
    pos = np.empty((T, J, 3))
    world = np.empty((T, J, 3, 3))
    for j, p in enumerate(np.asarray(parents)):
        if p < 0:
            world[:, j] = rot[:, j]
            pos[:, j] = trans[:, j]
        else:
            assert p < j, "parents must precede children"
            world[:, j] = world[:, p] @ rot[:, j]
            pos[:, j] = pos[:, p] + (world[:, p] @ trans[:, j, :, None])[..., 0]
    return pos.astype(np.float32), world.astype(np.float32)


def forward_kinematics(clip: BvhClip) -> tuple[np.ndarray, np.ndarray]:
    """World joint positions and rotations of a clip, in the BVH's own frame, metres.

    Args:
        clip: a clip from :func:`~loosefit.motion.bvh.read_bvh`.

    Returns:
        positions: (T, J, 3) float32 world joint positions.
        world_rotations: (T, J, 3, 3) float32 world rotations.
    """
    return forward_kinematics_arrays(clip.parents, clip.rotations, clip.local_translations)


def end_site_positions(clip: BvhClip) -> dict[int, np.ndarray]:
    """World positions of the End Sites (finger, toe and head tips).

    Args:
        clip: a clip from :func:`~loosefit.motion.bvh.read_bvh`.

    Returns:
        {j: (T, 3) float32} keyed by the index of the joint carrying the End Site.
    """
    pos, world = forward_kinematics(clip)
    return {j: pos[:, j] + world[:, j] @ off for j, off in clip.end_offsets.items()}


def _rest_positions(parents: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """(J,) parents, (J, 3) offsets -> (J, 3) positions with every rotation zero."""
    pos = np.zeros((len(parents), 3))
    for j, p in enumerate(parents):
        pos[j] = offsets[j] + (pos[p] if p >= 0 else 0.0)
    return pos


def rest_positions(clip: BvhClip) -> np.ndarray:
    """Joint positions at zero rotation with the root at its OFFSET (the skeleton's rest pose).

    Args:
        clip: a clip from :func:`~loosefit.motion.bvh.read_bvh`.

    Returns:
        (J, 3) float32 positions, metres, in the BVH's own frame.
    """
    return _rest_positions(clip.parents, clip.offsets.astype(np.float64)).astype(np.float32)
