"""Motion features: invariance to where the dancer stands and faces; root frames."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from loosefit.errors import LoosefitInputError
from loosefit.model.motion_encoder import MotionEncoderConfig
from loosefit.model.motion_features import (
    LOWER_BODY_JOINTS,
    feature_joints,
    frame_features,
    heading_frames,
    heading_yaw,
    motion_features,
    num_features,
    root_frames,
    yaw_matrix,
)
from loosefit.motion.motions import load_motion


def _moved(rotations, root, yaw: float, shift: tuple[float, float]):
    R = yaw_matrix(torch.tensor(yaw, dtype=torch.float64))
    rot = rotations.double().clone()
    rot[:, 0] = R @ rot[:, 0]
    moved = root.double() @ R.T + torch.tensor([shift[0], shift[1], 0.0], dtype=torch.float64)
    return rot, moved


def test_features_ignore_a_global_shift_and_turn(avatar):
    m = load_motion("walk", avatar).slice(0, 40)
    rot, root = torch.from_numpy(m.rotations), torch.from_numpy(m.root_translation)
    f = motion_features(rot, root, m.fps, avatar.floor_height)
    assert f.shape == (40, num_features(len(avatar.joint_names)))
    for yaw, shift in ((2.5, (3.0, -7.0)), (-math.pi + 0.01, (0.0, 40.0))):
        g = motion_features(*_moved(rot, root, yaw, shift), m.fps, avatar.floor_height)
        torch.testing.assert_close(g, f, atol=1e-4, rtol=0)


def test_features_see_speed_turning_and_height(avatar):
    m = load_motion("walk", avatar).slice(0, 40)
    rot, root = torch.from_numpy(m.rotations), torch.from_numpy(m.root_translation)
    f = motion_features(rot, root, m.fps, avatar.floor_height)
    J = len(avatar.joint_names)
    vel = f[:, 6 * J : 6 * J + 3]
    speed = np.linalg.norm(np.diff(m.root_translation, axis=0), axis=-1) * m.fps
    np.testing.assert_allclose(vel[1:].norm(dim=-1).numpy(), speed, atol=1e-4)
    assert (vel[0] == 0).all()
    # Walking forward: the heading-frame velocity points along -Y (the facing).
    assert vel[5:, 1].mean() < -0.3
    slow = motion_features(rot, root, m.fps / 2, avatar.floor_height)
    torch.testing.assert_close(slow[:, 6 * J : 6 * J + 4], f[:, 6 * J : 6 * J + 4] / 2)
    lifted = motion_features(rot, root + torch.tensor([0, 0, 0.1]), m.fps, avatar.floor_height)
    torch.testing.assert_close(lifted[:, -1], f[:, -1] + 0.1, atol=1e-5, rtol=0)


def test_root_frames_match_the_skinning_heading(avatar):
    m = load_motion("spin", avatar).slice(0, 30)
    body = avatar.pose_motion(m)
    H0, p0 = heading_frames(body.joint_transforms[:, 0].float())
    H, p = root_frames(torch.from_numpy(m.rotations), torch.from_numpy(m.root_translation))
    torch.testing.assert_close(H, H0, atol=1e-5, rtol=0)
    torch.testing.assert_close(p, p0, atol=1e-5, rtol=0)


def test_lower_body_features_are_the_spine_and_legs_alone(avatar):
    m = load_motion("walk", avatar).slice(0, 20)
    rot, root = torch.from_numpy(m.rotations), torch.from_numpy(m.root_translation)
    names = list(avatar.joint_names)
    lower = feature_joints(names, "lower")
    assert [names[i] for i in lower] == [n for n in names if n in LOWER_BODY_JOINTS[1:]]
    assert feature_joints(names, "all") == list(range(1, len(names)))
    f = motion_features(rot, root, m.fps, avatar.floor_height, lower)
    assert f.shape == (20, num_features(len(lower) + 1))
    full = motion_features(rot, root, m.fps, avatar.floor_height)
    # the same joint blocks and the same root features as the full set
    blocks = full[:, : 6 * (len(names) - 1)].view(20, -1, 6)
    torch.testing.assert_close(
        f[:, : 6 * len(lower)].view(20, -1, 6), blocks[:, [i - 1 for i in lower]]
    )
    torch.testing.assert_close(f[:, 6 * len(lower) :], full[:, 6 * (len(names) - 1) :])
    # moving an arm changes the full features only
    waved = rot.clone()
    waved[:, names.index("LeftArm")] = yaw_matrix(torch.tensor(1.0, dtype=torch.float64))
    assert not torch.equal(motion_features(waved, root, m.fps, avatar.floor_height), full)
    torch.testing.assert_close(motion_features(waved, root, m.fps, avatar.floor_height, lower), f)


def test_joint_sets_need_their_joints(avatar):
    with pytest.raises(LoosefitInputError, match="joints.*one of"):
        feature_joints(avatar.joint_names, "arms")
    with pytest.raises(LoosefitInputError, match="MotionEncoderConfig.*joints"):
        MotionEncoderConfig(joints="upper")
    names = [n for n in avatar.joint_names if n != "LeftLeg"]
    with pytest.raises(LoosefitInputError, match="LeftLeg"):
        feature_joints(names, "lower")


def test_frame_features_one_frame_at_a_time_in_float32(avatar):
    """The ONNX graph's features (one frame and the root before it, float32) are the
    motion's (double precision, then rounded), a turn across +-pi included."""
    m = load_motion("spin", avatar).slice(0, 60)
    rot, root = torch.from_numpy(m.rotations).float(), torch.from_numpy(m.root_translation)
    whole = motion_features(rot, root, m.fps, avatar.floor_height)
    before = torch.cat([rot[:1, 0], rot[:-1, 0]])
    root_before = torch.cat([root[:1], root[:-1]])
    frames = frame_features(
        rot, root.float(), before, root_before.float(), m.fps, avatar.floor_height
    )
    assert frames.dtype == torch.float32
    torch.testing.assert_close(frames, whole, atol=1e-4, rtol=0)
    J = len(avatar.joint_names)
    turn = whole[:, 6 * J + 3]
    yaw = np.unwrap([float(y) for y in heading_yaw(rot[:, 0].double())])
    assert yaw.max() - yaw.min() > 2 * math.pi  # a whole turn: the heading wraps, the rate not
    np.testing.assert_allclose(turn[1:].numpy(), np.diff(yaw) * m.fps, atol=1e-3)
