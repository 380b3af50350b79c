"""The pelvis re-posed at another pitch (loosefit.motion.pelvis)."""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.motion.motions import load_motion
from loosefit.motion.pelvis import lateral_axes, pelvis_pitch, pitch_pelvis


def test_the_pelvis_pitches_and_the_body_below_and_above_keeps_its_pose(avatar):
    motion = load_motion("spin", avatar).slice(10, 30)  # turning: every heading
    pitched = pitch_pelvis(motion, avatar.skeleton.parents, 12.0)
    np.testing.assert_allclose(
        pelvis_pitch(pitched.rotations), pelvis_pitch(motion.rotations) + 12.0, atol=1e-3
    )
    # the heading is kept: the lateral axis is the same
    np.testing.assert_allclose(
        lateral_axes(pitched.rotations[:, 0]), lateral_axes(motion.rotations[:, 0]), atol=1e-5
    )
    before = avatar.pose_motion(motion).joint_poses.numpy()
    after = avatar.pose_motion(pitched).joint_poses.numpy()
    np.testing.assert_allclose(after[:, 1:, :3, :3], before[:, 1:, :3, :3], atol=1e-5)
    assert np.abs(after[:, 0, :3, :3] - before[:, 0, :3, :3]).max() > 0.1
    moved = np.linalg.norm(after[:, :, :3, 3] - before[:, :, :3, 3], axis=-1)
    assert moved.max() < 0.03  # the joint centres the pelvis carries: a centimetre or two
    np.testing.assert_array_equal(pitched.root_translation, motion.root_translation)
    assert pitched.name == "pitch:12:spin" and pitched.meta["pelvis_pitch"] == 12.0


def test_pitching_back_gives_the_motion_back(avatar):
    motion = load_motion("kick", avatar).slice(0, 20)
    parents = avatar.skeleton.parents
    back = pitch_pelvis(pitch_pelvis(motion, parents, -20.0), parents, 20.0)
    np.testing.assert_allclose(back.rotations, motion.rotations, atol=1e-5)
    assert back.meta["pelvis_pitch"] == 0.0


def test_the_spec_pitches_the_motion_after_it(avatar):
    spin = load_motion("spin", avatar)
    spec = load_motion("pitch:-7.5:spin", avatar)
    np.testing.assert_array_equal(
        spec.rotations, pitch_pelvis(spin, avatar.skeleton.parents, -7.5).rotations
    )
    assert load_motion("frames:0:5:pitch:5:spin", avatar).num_frames == 5


@pytest.mark.parametrize("degrees", [46.0, float("nan"), float("inf")])
def test_a_pitch_beyond_the_bound_is_refused(avatar, degrees):
    motion = load_motion("spin", avatar).slice(0, 3)
    with pytest.raises(LoosefitInputError) as err:
        pitch_pelvis(motion, avatar.skeleton.parents, degrees)
    assert err.value.field == "pelvis pitch" and "-45 to 45" in str(err.value)


def test_parents_of_another_skeleton_are_refused(avatar):
    motion = load_motion("spin", avatar).slice(0, 3)
    with pytest.raises(LoosefitInputError, match="parents"):
        pitch_pelvis(motion, np.array([-1, 0, 1]), 5.0)


def test_a_pelvis_facing_straight_down_has_no_heading():
    R = np.array([[[1.0, 0, 0], [0, 0, 1], [0, -1, 0]]])  # forward (-Y column) is -Z
    with pytest.raises(LoosefitInputError, match="frame 0 faces vertically"):
        lateral_axes(R)
