"""A rollout's timeline: warm frames of the rest pose where the motion starts, the blend into
its first frame, then the motion itself, frame for frame."""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.inference.timeline import RolloutConfig, rollout_timeline
from loosefit.types import Motion

FLOOR = 0.9


def _motion(T: int = 6, fps: float = 30.0) -> Motion:
    """Three joints facing -Y (identity), the root walking along +X and bending down."""
    rot = np.tile(np.eye(3, dtype=np.float32), (T, 3, 1, 1))
    c, s = np.cos(0.4), np.sin(0.4)
    rot[:, 1] = [[1, 0, 0], [0, c, -s], [0, s, c]]  # the second joint bent
    root = np.stack([0.3 + 0.01 * np.arange(T), np.full(T, -0.2), np.full(T, 0.8)], 1)
    return Motion(("Hips", "Spine", "Head"), rot, root, fps, "walk")


def test_warm_frames_then_the_blend_then_the_motion():
    motion = _motion()
    rot, root, P = rollout_timeline(motion, FLOOR, warm_frames=5, blend_seconds=0.5)
    assert P == 5 + 15  # the warm frames, then round(0.5 s * 30 fps) frames of blend
    assert rot.shape == (P + 6, 3, 3, 3) and root.shape == (P + 6, 3)
    np.testing.assert_array_equal(rot[P:], motion.rotations)
    np.testing.assert_array_equal(root[P:], motion.root_translation)
    # the warm frames: the rest pose standing on the floor where the motion starts
    np.testing.assert_array_equal(rot[:5], np.broadcast_to(np.eye(3), (5, 3, 3, 3)))
    np.testing.assert_allclose(root[:5], np.broadcast_to([0.3, -0.2, FLOOR], (5, 3)), atol=1e-7)
    # the blend: the root lowered with smoothstep timing, strictly between the two poses
    w = np.arange(1, 16) / 16.0
    w = w * w * (3 - 2 * w)
    np.testing.assert_allclose(root[5:P, 2], FLOOR + w * (0.8 - FLOOR), atol=1e-6)
    angle = np.arctan2(rot[5:P, 1, 2, 1], rot[5:P, 1, 1, 1])
    np.testing.assert_allclose(angle, 0.4 * w, atol=1e-5)  # the bend slerped


@pytest.mark.parametrize(("warm", "blend", "P"), [(1, 0.0, 1), (0, 0.1, 1 + 3), (3, 0.2, 3 + 6)])
def test_the_frames_before_the_motion(warm, blend, P):
    rot, root, got = rollout_timeline(_motion(), FLOOR, warm, blend)
    assert got == P and len(rot) == len(root) == P + 6


def test_the_defaults_are_the_simulator_s_blend():
    config = RolloutConfig()
    assert (config.warm_frames, config.blend_seconds, config.max_distance) == (5, 0.5, 3.0)
