"""The pelvis re-posed at another pitch, the rest of the body as captured.

Captures of one dancer disagree on where the pelvis points: the CMU salsa clips hold its
forward axis 3-9 degrees below the horizontal, the ballet clips 10-30, from where the
markers sat rather than how the dancer stood. A skirt hangs from the waistband, which
follows the pelvis, so the same step at another pelvis pitch is another simulation: data
that teaches a model what the pitch does to the cloth instead of which clip it marks.

:func:`pitch_pelvis` turns the root about its heading's lateral axis (the horizontal axis
at right angles to the way the pelvis faces) and gives each of its children the local
rotation that keeps that child's world rotation: the spine and the legs keep their
captured orientations, and only the pelvis (and the hips' joint centres, carried by it
a centimetre or two) moves.
"""

from __future__ import annotations

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.geometry.rotations import axis_angle_to_matrix
from loosefit.types import Motion

# what a spec may ask for: a pitch a body can take on top of a capture's
MAX_PITCH_DEGREES = 45.0


def pelvis_pitch(rotations: np.ndarray) -> np.ndarray:
    """(T,) degrees: the pelvis's forward axis (-Y at rest) above the horizontal, from
    (T, J, 3, 3) local rotations (the root's first)."""
    forward = -np.asarray(rotations[:, 0, :, 1], np.float64)  # (T, 3)
    return np.degrees(np.arcsin(np.clip(forward[:, 2], -1.0, 1.0)))


def lateral_axes(root_rotations: np.ndarray) -> np.ndarray:
    """(T, 3) unit horizontal axes about which a positive turn raises the pelvis's forward
    axis: ``forward x up`` of the heading (the forward axis's horizontal part).

    Raises:
        LoosefitInputError: a frame whose pelvis faces straight up or down (no heading).
    """
    forward = -np.asarray(root_rotations[:, :, 1], np.float64)  # (T, 3)
    flat = forward * np.array([1.0, 1.0, 0.0])
    norm = np.linalg.norm(flat, axis=1)
    if (norm < 1e-6).any():
        t = int(np.argmax(norm < 1e-6))
        raise LoosefitInputError(
            "motion",
            "rotations",
            "a pelvis with a heading (not facing straight up or down)",
            f"frame {t} faces vertically",
        )
    heading = flat / norm[:, None]
    return np.cross(heading, np.array([0.0, 0.0, 1.0]))


def pitch_pelvis(motion: Motion, parents: np.ndarray, degrees: float) -> Motion:
    """The motion with the pelvis pitched ``degrees`` more, its children's world rotations kept.

    Args:
        motion: T frames on a skeleton whose root is joint 0.
        parents: (J,) each joint's parent index, -1 for the root (the avatar's skeleton).
        degrees: added to the pelvis's pitch (:func:`pelvis_pitch`): positive raises the
            front of the pelvis (tips it back), negative tips it forward; at most
            :data:`MAX_PITCH_DEGREES` either way.

    Returns:
        A new :class:`Motion` of the same frames, joints, rate and root position, named
        ``pitch:DEGREES:NAME``, its ``meta["pelvis_pitch"]`` the degrees added.

    Raises:
        LoosefitInputError: ``degrees`` not finite or beyond the bound; ``parents`` not the
            motion's skeleton's.
    """
    if not (np.isfinite(degrees) and abs(degrees) <= MAX_PITCH_DEGREES):
        raise LoosefitInputError(
            f"motion '{motion.name}'",
            "pelvis pitch",
            f"degrees from -{MAX_PITCH_DEGREES:g} to {MAX_PITCH_DEGREES:g}",
            repr(degrees),
        )
    parents = np.asarray(parents)
    if parents.shape != (motion.num_joints,) or parents[0] != -1:
        raise LoosefitInputError(
            f"motion '{motion.name}'",
            "parents",
            f"({motion.num_joints},) parent indices with the root first",
            f"shape {parents.shape}" + ("" if len(parents) == 0 else f", root {parents[0]}"),
        )
    rot = motion.rotations.astype(np.float64)  # (T, J, 3, 3)
    root = rot[:, 0]
    turn = axis_angle_to_matrix(lateral_axes(root) * np.radians(degrees)).astype(np.float64)
    new_root = turn @ root
    out = rot.copy()
    out[:, 0] = new_root
    # a child's world rotation G_c = G_root @ R_c stays: R_c' = G_root'^T G_root R_c
    keep = new_root.transpose(0, 2, 1) @ root  # (T, 3, 3)
    for c in np.nonzero(parents == 0)[0]:
        out[:, c] = keep @ rot[:, c]
    meta = {**motion.meta, "pelvis_pitch": float(motion.meta.get("pelvis_pitch", 0.0)) + degrees}
    return Motion(
        motion.joint_names,
        out.astype(np.float32),
        motion.root_translation,
        motion.fps,
        f"pitch:{degrees:g}:{motion.name}",
        meta,
    )
