"""A rollout's timeline: the rest pose, the blend into the motion, then the motion.

A rollout starts as the simulator does: the body stands in the rest pose for a few
frames (``warm_frames``, which also warm the GRU up), then blends into the motion's first
frame (``blend_seconds``; :func:`loosefit.motion.chain.preroll`). Training runs the same
timeline, so the encoder has seen every kind of frame it meets at inference.

Numpy alone (no torch), so that the ONNX reference loop
(:mod:`loosefit.inference.onnx.runtime`) runs the same timeline;
:func:`loosefit.inference.rollout.timeline` gives it as tensors.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from loosefit.motion.chain import preroll
from loosefit.types import Motion


@dataclass
class RolloutConfig:
    """The timeline before a motion's first frame, and when a rollout has failed."""

    warm_frames: int = 5  # rest-pose frames before the blend
    blend_seconds: float = 0.5  # rest pose to the motion's first frame (the simulator's blend)
    max_distance: float = 3.0  # m from the root: a vertex farther away means the rollout diverged


class Timeline(NamedTuple):
    """A motion on the rollout timeline: P frames before its first, then its T frames
    (numpy arrays from :func:`rollout_timeline`, float32 tensors from
    :func:`loosefit.inference.rollout.timeline`)."""

    rotations: np.ndarray  # (P + T, J, 3, 3) joint rotations
    root_translation: np.ndarray  # (P + T, 3) m, the root's position
    preroll: int  # P: the frames before the motion's first


def rollout_timeline(
    motion: Motion, floor_height: float, warm_frames: int, blend_seconds: float
) -> Timeline:
    """A rollout's frames: ``warm_frames`` of the rest pose, the blend into the motion's
    first frame over ``blend_seconds`` (:func:`preroll`), then the motion (what
    :func:`timeline` and the ONNX reference loop run).

    Returns:
        :class:`Timeline`: rotations (P + T, J, 3, 3), root translations (P + T, 3), and
        P, the number of frames before the motion's first.
    """
    settle = max(warm_frames - 1, 0) / motion.fps
    rot, root, _ = preroll(motion, floor_height, settle, blend_seconds)
    return Timeline(
        np.concatenate([rot, motion.rotations]),
        np.concatenate([root, motion.root_translation]),
        len(rot),
    )
