"""Resampling and glitch filtering against analytic motions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.geometry.rotations import euler_to_matrix, rotation_angle
from loosefit.motion.motions import load_motion
from loosefit.motion.resample import (
    detect_rotation_glitches,
    filter_rotation_glitches,
    resample_linear,
    resample_motion,
    resample_rotations,
    resample_times,
    retime_motion,
)
from loosefit.types import Motion

NAMES = ("root", "spine", "arm")


def spinning_motion(num_frames: int, fps: float, deg_per_s: float) -> Motion:
    """Joint 1 turns about Z at a constant rate; the root translates at constant velocity."""
    t = np.arange(num_frames) / fps
    rot = np.broadcast_to(np.eye(3), (num_frames, 3, 3, 3)).copy()
    rot[:, 1] = euler_to_matrix((deg_per_s * t)[:, None], "Z")
    translation = np.stack([0.5 * t, -0.25 * t, np.full_like(t, 0.9)], axis=1)
    return Motion(NAMES, rot, translation, fps, "spin")


@pytest.mark.parametrize(
    ("frames", "src", "dst", "expected"),
    [
        (2242, 120.0, 30.0, math.floor(2241 / 120 * 30) + 1),  # 561
        (121, 120.0, 30.0, 31),  # exact multiple: the last frame is kept
        (100, 30.0, 120.0, 397),
        (1, 120.0, 30.0, 1),
        (2242, 1 / 0.008333, 30.0, math.floor(2241 * 0.008333 * 30) + 1),
    ],
)
def test_frame_count(frames, src, dst, expected):
    index, weight = resample_times(frames, src, dst)
    assert len(index) == len(weight) == expected
    assert index.min() >= 0 and index.max() <= max(frames - 2, 0)
    assert ((weight >= 0) & (weight <= 1)).all()


def test_resample_motion_frame_count_and_fps():
    motion = spinning_motion(2242, 120.0, 90.0)
    out = resample_motion(motion, 30.0)
    assert out.num_frames == math.floor(motion.duration * 30.0) + 1 == 561
    assert out.fps == 30.0 and out.joint_names == NAMES
    assert out.meta["resampled_from_fps"] == 120.0
    # 120 -> 30 is every fourth frame exactly.
    np.testing.assert_allclose(out.rotations, motion.rotations[::4], atol=1e-6)
    np.testing.assert_allclose(out.root_translation, motion.root_translation[::4], atol=1e-6)


def test_retimed_motion_plays_faster_at_the_same_rate():
    motion = spinning_motion(121, 30.0, 60.0)
    fast = retime_motion(motion, 2.0)
    assert fast.fps == 30.0 and fast.num_frames == 61 and fast.name == "speed:2:spin"
    # twice as fast is every other frame; the root covers its path in half the time
    np.testing.assert_allclose(fast.rotations, motion.rotations[::2], atol=1e-6)
    np.testing.assert_allclose(fast.root_translation, motion.root_translation[::2], atol=1e-6)
    velocity = np.diff(fast.root_translation, axis=0) * fast.fps
    np.testing.assert_allclose(velocity[:, :2], [[1.0, -0.5]] * 60, atol=1e-4)
    angle = rotation_angle(fast.rotations[0, 1], fast.rotations[1, 1]) * 180 / math.pi
    assert angle == pytest.approx(4.0, abs=1e-3)  # 120 deg/s at 30 fps
    slow = retime_motion(motion, 0.5)
    assert slow.num_frames == 241 and retime_motion(slow, 2.0).meta["speed"] == 1.0
    np.testing.assert_allclose(slow.rotations[::2], motion.rotations, atol=1e-6)
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(LoosefitInputError, match="speed"):
            retime_motion(motion, bad)


def test_speed_spec(avatar):
    a = load_motion("speed:1.5:spin", avatar, max_frames=10)
    b = retime_motion(load_motion("spin", avatar), 1.5).slice(0, 10)
    np.testing.assert_array_equal(a.rotations, b.rotations)
    np.testing.assert_array_equal(a.root_translation, b.root_translation)
    assert a.name == "speed:1.5:spin" and a.fps == 30.0
    for bad in ("speed:fast:spin", "speed:0:spin", "speed:2", "speed:-1:spin"):
        with pytest.raises(LoosefitInputError, match="speed:FACTOR:MOTION"):
            load_motion(bad, avatar)


def test_identity_stays_identity():
    motion = Motion(NAMES, np.broadcast_to(np.eye(3), (50, 3, 3, 3)), np.zeros((50, 3)), 120.0)
    out = resample_motion(motion, 47.0)
    np.testing.assert_allclose(out.rotations, np.eye(3)[None, None].repeat(3, 1).repeat(20, 0))


def test_constant_angular_velocity_matches_analytic_angle():
    # 200 deg/s at 24 fps is 8.33 degrees a frame; resample to an unrelated rate.
    motion = spinning_motion(49, 24.0, 200.0)
    out = resample_motion(motion, 37.0)
    t = np.arange(out.num_frames) / 37.0
    expected = euler_to_matrix((200.0 * t)[:, None], "Z")
    np.testing.assert_allclose(out.rotations[:, 1], expected, atol=1e-5)
    np.testing.assert_allclose(
        out.rotations[:, [0, 2]],
        np.eye(3)[None, None].repeat(2, 1).repeat(out.num_frames, 0),
        atol=1e-6,
    )


def test_slerp_takes_the_short_way_across_the_antipode():
    # 170 degrees then 190 (= -170) degrees: the short way passes through 180.
    rot = euler_to_matrix(np.array([[170.0], [190.0]]), "Z")[:, None]  # (2, 1, 3, 3)
    mid = resample_rotations(rot, 1.0, 2.0)[1, 0]
    np.testing.assert_allclose(mid, euler_to_matrix([180.0], "Z"), atol=1e-6)


def test_pure_translation_is_linear():
    motion = spinning_motion(121, 120.0, 0.0)
    out = resample_motion(motion, 50.0)
    t = np.arange(out.num_frames) / 50.0
    np.testing.assert_allclose(out.root_translation[:, 0], 0.5 * t, atol=1e-6)
    np.testing.assert_allclose(out.root_translation[:, 1], -0.25 * t, atol=1e-6)
    np.testing.assert_allclose(out.root_translation[:, 2], 0.9, atol=1e-6)


def test_resample_linear_shapes_and_values():
    x = np.arange(10.0)[:, None, None] * np.ones((10, 2, 3))  # (T, 2, 3), value = frame
    out = resample_linear(x, 10.0, 25.0)
    assert out.shape == (23, 2, 3)
    np.testing.assert_allclose(out[:, 0, 0], np.arange(23) * 0.4)
    assert resample_linear(np.arange(5), 1.0, 2.0).dtype == np.float64


def test_bad_fps():
    with pytest.raises(LoosefitInputError, match="dst_fps"):
        resample_linear(np.zeros((4, 3)), 30.0, 0.0)
    with pytest.raises(LoosefitInputError, match="fps"):
        resample_motion(spinning_motion(4, 30.0, 10.0), -1.0)


def test_glitch_filter_removes_a_single_frame_pop():
    # A foot turning steadily at 2 degrees a frame, with a 40-degree pop at frame 50.
    T = 120
    angles = np.zeros((T, 3))
    angles[:, 0] = 2.0 * np.arange(T)
    clean = euler_to_matrix(angles, "ZXY")
    popped = angles.copy()
    popped[50, 1] += 40.0
    rot = np.stack([clean, euler_to_matrix(popped, "ZXY")], axis=1)  # (T, 2, 3, 3)
    glitches = detect_rotation_glitches(rot, 120.0)
    assert glitches.shape == (T, 2)
    assert np.argwhere(glitches).tolist() == [[50, 1]]
    out = filter_rotation_glitches(rot, 120.0)
    np.testing.assert_allclose(out[:, 0], clean, atol=1e-6)
    np.testing.assert_allclose(out[:, 1], clean, atol=1e-5)  # midpoint of neighbours
    # The same pop at 30 fps: the threshold scales with the frame rate (60 deg/frame),
    # so a 40-degree step is ordinary motion there.
    assert not detect_rotation_glitches(rot, 30.0).any()


def test_glitch_filter_keeps_real_motion():
    # Fast but smooth (12 deg a frame at 120 fps), a reversal spread over frames, and a
    # zigzag (pops at frames 20 and 22, so 20, 21 and 22 all meet the rule): nothing is
    # an isolated single-frame pop.
    T = 60
    fast = 12.0 * np.arange(T)
    reversal = 30.0 * np.sin(np.linspace(0, 4 * np.pi, T))
    wobble = np.zeros(T)
    wobble[[20, 22]] = 40.0
    angles = np.stack([fast, reversal, wobble], axis=1)[..., None]  # (T, 3, 1)
    rot = euler_to_matrix(angles, "X")
    assert not detect_rotation_glitches(rot, 120.0).any()
    np.testing.assert_allclose(filter_rotation_glitches(rot, 120.0), rot, atol=0)
    steps = rotation_angle(rot[:-1], rot[1:])
    assert np.rad2deg(steps[:, 0]).min() == pytest.approx(12.0, abs=1e-3)


def test_frames_spec(avatar):
    """``frames:START:STOP:MOTION``: a stretch of any motion, also inside speed: and mirror:."""
    spin = load_motion("spin", avatar)
    part = load_motion("frames:20:50:spin", avatar)
    assert part.num_frames == 30
    np.testing.assert_array_equal(part.rotations, spin.rotations[20:50])
    np.testing.assert_array_equal(part.root_translation, spin.root_translation[20:50])
    fast = load_motion("speed:1.5:frames:20:50:spin", avatar)
    np.testing.assert_array_equal(fast.rotations, retime_motion(part, 1.5).rotations)
    for bad in ("frames:50:20:spin", "frames:a:b:spin", "frames:0:10", "frames:-1:5:spin"):
        with pytest.raises(LoosefitInputError, match="frames:START:STOP"):
            load_motion(bad, avatar)
    with pytest.raises(LoosefitInputError, match="STOP <="):
        load_motion(f"frames:0:{spin.num_frames + 1}:spin", avatar)
