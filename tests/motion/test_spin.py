"""Spins on the spot added to a motion (loosefit.motion.spin)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from loosefit.errors import LoosefitInputError
from loosefit.model.motion_features import heading_yaw
from loosefit.motion.motions import load_motion
from loosefit.motion.spin import (
    SPIN_FIRST_SECONDS,
    SPIN_RAMP_SECONDS,
    Spin,
    read_spin,
    spin_count,
    spin_motion,
    spin_rates,
)

SPIN_SECONDS = Spin(1.0).seconds  # the default spin: 1.6 s, one starting every 3 s
SPIN_EVERY_SECONDS = Spin(1.0).every


def _yaw(motion) -> np.ndarray:
    """(T,) the heading, unwrapped."""
    return np.unwrap(heading_yaw(torch.from_numpy(motion.rotations[:, 0]).double()).numpy())


def test_each_spin_peaks_at_its_rate_and_turns_the_other_way_from_the_last():
    fps = 30.0
    rates = spin_rates(300, fps, 1.0)  # 10 s: spins at 1, 4 and 7 s
    t = np.arange(300) / fps
    assert spin_count(300, fps) == 3
    for k in range(3):
        start = SPIN_FIRST_SECONDS + k * SPIN_EVERY_SECONDS
        inside = (t >= start) & (t <= start + SPIN_SECONDS)
        hold = (t >= start + SPIN_RAMP_SECONDS) & (t <= start + SPIN_SECONDS - SPIN_RAMP_SECONDS)
        np.testing.assert_allclose(rates[hold], (-1) ** k * 2 * math.pi, rtol=1e-12)
        assert np.sign(rates[inside & (rates != 0)]).tolist() == [(-1) ** k] * int(
            (inside & (rates != 0)).sum()
        )
    quiet = np.ones(300, bool)
    for k in range(3):
        start = SPIN_FIRST_SECONDS + k * SPIN_EVERY_SECONDS
        quiet &= ~((t > start) & (t < start + SPIN_SECONDS))
    assert np.abs(rates[quiet]).max() < 1e-9
    # each spin turns (SPIN_SECONDS - SPIN_RAMP_SECONDS) times its peak: 1.2 turns at 1 a second
    one = rates[t < SPIN_FIRST_SECONDS + SPIN_EVERY_SECONDS].sum() / fps
    assert one == pytest.approx(2 * math.pi * (SPIN_SECONDS - SPIN_RAMP_SECONDS), rel=1e-3)


def test_a_spin_that_would_not_end_in_the_clip_is_left_out():
    fps = 30.0
    whole = int((SPIN_FIRST_SECONDS + SPIN_SECONDS) * fps) + 1
    assert spin_count(whole, fps) == 1 and spin_count(whole - 1, fps) == 0
    assert np.abs(spin_rates(whole - 1, fps, 1.0)).max() == 0.0
    assert whole == 79  # 2.6 s after the first frame


def test_the_body_turns_about_the_pelvis_and_keeps_its_pose_and_path(avatar):
    motion = load_motion("walk", avatar)  # 4 s or more: one spin at least
    spun = spin_motion(motion, -1.5)
    rates = np.diff(_yaw(spun) - _yaw(motion)) * motion.fps
    expected = spin_rates(motion.num_frames, motion.fps, -1.5)
    np.testing.assert_allclose(rates, 0.5 * (expected[1:] + expected[:-1]), atol=1e-3)
    assert rates.min() == pytest.approx(-1.5 * 2 * math.pi, rel=1e-3)  # the first turns right
    np.testing.assert_array_equal(spun.rotations[:, 1:], motion.rotations[:, 1:])
    np.testing.assert_array_equal(spun.root_translation, motion.root_translation)
    # the whole body turns: each joint's world rotation is the turn times the captured one
    before = avatar.pose_motion(motion).joint_poses.numpy()[..., :3, :3]
    after = avatar.pose_motion(spun).joint_poses.numpy()[..., :3, :3]
    turn = after[:, 0] @ before[:, 0].transpose(0, 2, 1)  # (T, 3, 3)
    np.testing.assert_allclose(after, turn[:, None] @ before, atol=1e-5)
    np.testing.assert_allclose(
        turn[:, 2], np.broadcast_to([0.0, 0.0, 1.0], (len(turn), 3)), atol=1e-5
    )
    assert spun.name == "spin:-1.5:walk" and spun.meta["spins"] == spin_count(
        motion.num_frames, motion.fps
    )


def test_the_spec_spins_the_motion_after_it(avatar):
    walk = load_motion("walk", avatar)
    spec = load_motion("spin:2:walk", avatar)
    np.testing.assert_array_equal(spec.rotations, spin_motion(walk, 2.0).rotations)
    assert load_motion("frames:0:5:spin:2:walk", avatar).num_frames == 5


@pytest.mark.parametrize("turns", [0.0, 4.5, -5.0, float("nan"), float("inf")])
def test_a_rate_that_is_zero_or_beyond_the_bound_is_refused(avatar, turns):
    motion = load_motion("walk", avatar)
    with pytest.raises(LoosefitInputError) as err:
        spin_motion(motion, turns)
    assert err.value.field == "spin" and "from -4 to 4" in str(err.value)


def test_a_motion_too_short_for_a_spin_is_refused_with_the_frames_it_needs(avatar):
    motion = load_motion("walk", avatar).slice(0, 30)
    with pytest.raises(LoosefitInputError, match=r"at least 79 frames at 30 fps.*found 30"):
        spin_motion(motion, 1.0)


@pytest.mark.parametrize(("frames", "fps"), [(169, 30.0), (141, 25.0), (337, 60.0), (300, 30.0)])
def test_the_count_is_the_spins_the_rates_hold(frames, fps):
    rates = spin_rates(frames, fps, 1.0)
    moving = np.abs(rates) > 0
    spins = int(moving[0]) + int((moving[1:] & ~moving[:-1]).sum())  # runs of turning
    assert spin_count(frames, fps) == spins


def test_the_default_spin_is_1_6_s_long_and_one_starts_every_3_s():
    assert (SPIN_SECONDS, SPIN_EVERY_SECONDS) == pytest.approx((1.6, 3.0))


def test_a_slow_spin_rises_over_its_ramp_peaks_once_and_turns_its_area():
    fps, slow = 30.0, Spin(1.0, ramp=0.8, hold=0.0)
    rates = spin_rates(300, fps, slow)
    t = np.arange(300) / fps
    first = t < SPIN_FIRST_SECONDS + slow.every
    peak = int(np.argmax(rates[first]))
    assert t[peak] == pytest.approx(SPIN_FIRST_SECONDS + 0.8, abs=0.5 / fps)
    assert rates[peak] == pytest.approx(2 * math.pi, rel=1e-3)
    # halfway up its ramp a smoothstep is at half the peak
    assert np.interp(SPIN_FIRST_SECONDS + 0.4, t, rates) == pytest.approx(math.pi, rel=1e-3)
    # a rise and a fall of 0.8 s each, no hold: 0.8 turns
    assert rates[first].sum() / fps == pytest.approx(2 * math.pi * 0.8, rel=1e-3)
    assert spin_count(300, fps, slow) == 3 and spin_count(300, fps, Spin(1.0, hold=2.0)) == 2


@pytest.mark.parametrize(
    ("text", "spin"),
    [
        ("1", Spin(1.0)),
        ("-0.5", Spin(-0.5)),
        ("1,ramp=0.8,hold=0", Spin(1.0, ramp=0.8, hold=0.0)),
        ("2,hold=1.5", Spin(2.0, hold=1.5)),
        ("1, ramp=0.4", Spin(1.0)),
    ],
)
def test_a_spin_reads_from_its_field_and_writes_it_back(text, spin):
    assert read_spin(text) == spin
    assert read_spin(spin.spec()) == spin and read_spin(spin.turns) == Spin(spin.turns)


def test_a_spin_names_only_what_differs_from_the_default():
    assert (Spin(1.0).spec(), Spin(1.0).label()) == ("1", "1")
    slow = Spin(1.0, ramp=0.8, hold=0.0)
    assert (slow.spec(), slow.label()) == ("1,ramp=0.8,hold=0", "1_ramp0.8_hold0")
    assert Spin(0.5, hold=2.0).label() == "0.5_hold2"


@pytest.mark.parametrize(
    "text",
    [
        "1,ramp=0.05",
        "1,ramp=3",
        "1,hold=-1",
        "1,hold=11",
        "1,twist=1",
        "1,ramp",
        "1,ramp=0.5,ramp=0.6",
        "fast",
        "0",
    ],
)
def test_a_spin_beyond_its_bounds_or_of_an_unknown_field_does_not_read(text):
    assert read_spin(text) is None


def test_the_spec_takes_a_ramp_and_a_hold_and_refuses_one_out_of_bounds(avatar):
    walk = load_motion("walk", avatar)
    slow = load_motion("spin:1,ramp=0.8,hold=0:walk", avatar)
    np.testing.assert_array_equal(slow.rotations, spin_motion(walk, Spin(1.0, 0.8, 0.0)).rotations)
    assert slow.name == "spin:1,ramp=0.8,hold=0:walk"
    with pytest.raises(LoosefitInputError, match=r"spin:TURNS:MOTION.*ramp from 0.1 to 2 s"):
        load_motion("spin:1,ramp=0:walk", avatar)


def test_a_motion_too_short_for_a_long_spin_is_refused_with_the_frames_it_needs(avatar):
    motion = load_motion("walk", avatar).slice(0, 100)
    with pytest.raises(LoosefitInputError, match=r"at least 139 frames at 30 fps.*3.6 s long"):
        spin_motion(motion, Spin(1.0, hold=2.8))
