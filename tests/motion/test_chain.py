"""Chaining motions: placement, continuity and the transition frames."""

from __future__ import annotations

import math

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.geometry.rotations import axis_angle_to_matrix, rotation_angle
from loosefit.motion.chain import chain_motions, heading_yaw, place_motion
from loosefit.types import Motion

JOINTS = ("Hips", "LeftUpLeg", "RightUpLeg")


def _walk(yaw: float, start: tuple[float, float], frames: int = 20, name: str = "walk") -> Motion:
    """Walking 1 m/s straight ahead, facing ``yaw``, knees swinging."""
    t = np.arange(frames) / 30.0
    aa = np.zeros((frames, 3, 3))
    aa[:, 0, 2] = yaw
    aa[:, 1, 0] = 0.4 * np.sin(4 * t)
    aa[:, 2, 0] = -0.4 * np.sin(4 * t)
    rot = axis_angle_to_matrix(aa.reshape(-1, 3)).reshape(frames, 3, 3, 3)
    forward = np.array([math.sin(yaw), -math.cos(yaw)])
    root = np.zeros((frames, 3))
    root[:, :2] = np.asarray(start) + t[:, None] * forward
    root[:, 2] = 0.9
    return Motion(JOINTS, rot, root, 30.0, name)


def test_heading_yaw_reads_the_facing():
    for yaw in (0.0, 0.5, -2.0, 3.0):
        R = axis_angle_to_matrix(np.array([0.0, 0.0, yaw]))
        assert heading_yaw(R) == pytest.approx(yaw, abs=1e-6)


def test_place_motion_turns_about_the_first_frame():
    m = _walk(0.0, (3.0, 4.0))
    placed = place_motion(m, math.pi / 2, np.array([-1.0, 2.0]))
    np.testing.assert_allclose(placed.root_translation[0], [-1.0, 2.0, 0.9], atol=1e-6)
    # Walking -Y turned by +90 degrees walks +X.
    step = placed.root_translation[-1] - placed.root_translation[0]
    assert step[0] > 0.5 and abs(step[1]) < 1e-5
    assert heading_yaw(placed.rotations[0, 0]) == pytest.approx(math.pi / 2, abs=1e-5)
    np.testing.assert_allclose(placed.rotations[:, 1:], m.rotations[:, 1:])


def test_chain_starts_each_clip_where_the_last_ended():
    a, b = _walk(0.3, (0.0, 0.0), 20, "a"), _walk(-1.2, (5.0, 5.0), 25, "b")
    chain = chain_motions([a, b], blend_seconds=0.2)
    assert chain.num_frames == 20 + 6 + 25
    assert chain.meta["segments"] == [("a", 0, 20), ("b", 26, 25)]
    np.testing.assert_allclose(chain.rotations[:20], a.rotations, atol=1e-6)
    np.testing.assert_allclose(chain.root_translation[:20], a.root_translation, atol=1e-6)
    # b is placed at a's end, facing a's heading, and keeps its own motion.
    np.testing.assert_allclose(
        chain.root_translation[26, :2], a.root_translation[-1, :2], atol=1e-5
    )
    assert heading_yaw(chain.rotations[26, 0]) == pytest.approx(0.3, abs=1e-5)
    np.testing.assert_allclose(chain.rotations[26:, 1:], b.rotations[:, 1:], atol=1e-6)
    # No jumps: per-frame rotation changes and root steps stay small through the seam.
    turn = rotation_angle(chain.rotations[1:], chain.rotations[:-1])
    assert turn.max() < 0.15
    assert np.linalg.norm(np.diff(chain.root_translation, axis=0), axis=-1).max() < 0.05


def test_chain_rejects_mismatched_clips():
    a = _walk(0.0, (0.0, 0.0))
    other = Motion(("Hips",), a.rotations[:, :1], a.root_translation, 30.0, "other")
    with pytest.raises(LoosefitInputError, match="joint_names"):
        chain_motions([a, other])
    slow = Motion(JOINTS, a.rotations, a.root_translation, 24.0, "slow")
    with pytest.raises(LoosefitInputError, match="fps"):
        chain_motions([a, slow])
    with pytest.raises(LoosefitInputError, match="at least one"):
        chain_motions([])
