"""The motion's turn and raised leg (loosefit.eval.motion_signals), on motions whose answers
are known."""

from types import SimpleNamespace

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.eval.motion_signals import (
    fastest_turn,
    highest_leg,
    spin_rate,
    turn_extent,
    turn_rate,
)


def yaw(angles: np.ndarray) -> np.ndarray:
    """(T, 3, 3) rotations about +Z by ``angles`` (T,)."""
    c, s = np.cos(angles), np.sin(angles)
    R = np.zeros((len(angles), 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1.0
    return R


def motion_turning(angles: np.ndarray, fps: float = 30.0) -> SimpleNamespace:
    """A motion of two joints whose root turns by ``angles`` (T,) about the vertical."""
    rotations = np.repeat(np.eye(3)[None, None], len(angles), 0).repeat(2, 1)
    rotations[:, 0] = yaw(angles)
    return SimpleNamespace(rotations=rotations, fps=fps)


def test_a_steady_spin_turns_at_its_rate_through_the_wrap_around():
    fps, omega = 30.0, 6.0  # rad/s, 0.2 rad a frame
    angles = omega * np.arange(90) / fps  # wraps past +-pi several times
    rate = turn_rate(motion_turning(angles, fps))
    assert rate.shape == (90,)
    np.testing.assert_allclose(np.abs(rate[5:-5]), omega, rtol=1e-6)


def test_the_fastest_turn_is_where_the_spin_peaks():
    fps = 30.0
    t = np.arange(120)
    speed = 8.0 * np.exp(-0.5 * ((t - 70) / 6.0) ** 2)  # rad/s, a burst around frame 70
    angles = np.cumsum(speed) / fps
    frame = fastest_turn(motion_turning(angles, fps))
    assert abs(frame - 70) <= 2
    rate = np.abs(turn_rate(motion_turning(angles, fps)))
    assert frame == int(np.argmax(rate))


def test_a_turn_s_extent_is_its_run_above_half_its_peak_and_the_angle_turned_in_it():
    fps = 30.0
    rate = np.zeros(100)
    rate[20:50] = -6.0  # 1 s at 6 rad/s, right
    rate[50:60] = 1.0  # the other way after it: not the same turn
    rate[60:70] = -6.0  # a second turn after a pause
    seconds, turns = turn_extent(rate, 30, fps)
    assert seconds == pytest.approx(1.0)
    assert turns == pytest.approx(6.0 / (2 * np.pi))
    rate[45:50] = -2.0  # slower than half the peak: the turn ends before it
    assert turn_extent(rate, 30, fps)[0] == pytest.approx(25 / fps)
    assert turn_extent(rate, 30, fps, fraction=0.3)[0] == pytest.approx(1.0)
    assert turn_extent(rate, 0, fps) == (0.0, 0.0)  # a still frame is no turn


def test_spin_rate_is_counter_clockwise_positive_and_checks_its_shape():
    fps = 30.0
    angles = 2.0 * np.arange(30) / fps
    np.testing.assert_allclose(spin_rate(yaw(angles), fps), 2.0, atol=1e-9)
    np.testing.assert_allclose(spin_rate(yaw(-angles), fps), -2.0, atol=1e-9)
    with pytest.raises(LoosefitInputError, match="root_rotations"):
        spin_rate(np.zeros((5, 3)), fps)


def test_highest_leg_against_a_plain_loop():
    rng = np.random.default_rng(0)
    z = rng.uniform(0.0, 0.6, size=(50, 2))
    best, height = 0, -1.0
    for i, (left, right) in enumerate(z):
        if abs(left - right) > height:
            best, height = i, abs(left - right)
    assert highest_leg(z) == (best, pytest.approx(height))
