"""How fast a motion turns (loosefit.eval.heading), against plain loops over frames."""

from __future__ import annotations

import math

import numpy as np
import pytest

from loosefit.eval.heading import fastest_turn, heading, turn_rate, yaw_rate

FPS = 30.0


def turning(yaw: np.ndarray, tilt: float = 0.2) -> np.ndarray:
    """(T, 3, 3) root rotations: a turn by ``yaw`` (rad) about +Z after a lean about X."""
    c, s = math.cos(tilt), math.sin(tilt)
    lean = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    out = []
    for a in yaw:
        ca, sa = math.cos(a), math.sin(a)
        out.append(np.array([[ca, -sa, 0], [sa, ca, 0], [0, 0, 1]]) @ lean)
    return np.asarray(out)


def wrapped(angle: float) -> float:
    """An angle in [-pi, pi]."""
    while angle > math.pi:
        angle -= 2 * math.pi
    while angle < -math.pi:
        angle += 2 * math.pi
    return angle


def window_mean(x: list[float], window: int) -> list[float]:
    """Centred mean over ``window`` values, the missing ones at the ends counted as 0."""
    half = window // 2
    return [
        sum(x[j] for j in range(i - half, i - half + window) if 0 <= j < len(x)) / window
        for i in range(len(x))
    ]


@pytest.fixture(scope="module")
def yaw():
    t = np.arange(40) / FPS
    return 2.5 * np.sin(2.0 * t) + 1.5 * t**2  # rad: past pi, turning both ways


def test_the_heading_is_the_turn_about_the_vertical(yaw):
    got = heading(turning(yaw))
    expect = [wrapped(a) for a in yaw]
    np.testing.assert_allclose(got, expect, atol=1e-12)


def test_the_gradient_rate_against_a_loop(yaw):
    rate = yaw_rate(turning(yaw), FPS, "gradient")
    T = len(yaw)
    expect = [yaw[1] - yaw[0]]
    expect += [(yaw[i + 1] - yaw[i - 1]) / 2 for i in range(1, T - 1)]
    expect += [yaw[-1] - yaw[-2]]
    np.testing.assert_allclose(rate, FPS * np.asarray(expect), atol=1e-9)


def test_the_step_rate_against_a_loop(yaw):
    rate = yaw_rate(turning(yaw), FPS, "step")
    assert rate.shape == (len(yaw) - 1,)
    expect = [FPS * (yaw[i + 1] - yaw[i]) for i in range(len(yaw) - 1)]
    np.testing.assert_allclose(rate, expect, atol=1e-9)


@pytest.mark.parametrize("difference", ["gradient", "step"])
def test_the_turn_rate_is_a_centred_mean_of_the_speed(yaw, difference):
    R = turning(yaw)
    speed = [abs(r) for r in yaw_rate(R, FPS, difference)]
    expect = window_mean(speed, 5)
    if difference == "step":
        expect = [0.0, *expect]
    np.testing.assert_allclose(turn_rate(R, FPS, 5, difference), expect, atol=1e-9)


def test_the_fastest_turn_is_where_the_spin_is():
    yaw = np.zeros(60)
    yaw[30:] = np.cumsum(np.full(30, 0.05))
    yaw[40:45] += np.cumsum(np.full(5, 0.4))  # a fast spin over frames 40-44
    yaw[45:] += 2.0
    for difference in ("gradient", "step"):
        frame = fastest_turn(turning(yaw), FPS, 5, difference)
        assert 40 <= frame <= 45, difference


def test_the_rates_keep_the_rotations_dtype(yaw):
    R = turning(yaw).astype(np.float32)
    assert heading(R).dtype == np.float32
    np.testing.assert_allclose(yaw_rate(R, FPS), yaw_rate(R.astype(np.float64), FPS), atol=1e-3)


def test_an_unknown_difference_is_refused(yaw):
    with pytest.raises(ValueError, match="difference"):
        yaw_rate(turning(yaw), FPS, "forward")
