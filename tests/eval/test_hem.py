"""The hem ring's signals (loosefit.eval.hem) on rings whose answers are known."""

from __future__ import annotations

import numpy as np

from loosefit.eval.hem import hem_flare, hem_speed, hem_tilt

T = 12


def test_hem_flare_and_speed():
    angles = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    ring = np.stack([np.cos(angles), np.sin(angles), np.zeros(16)], -1)  # radius 1
    radius = 0.2 + 0.01 * np.arange(T)
    garment = radius[:, None, None] * ring[None] + np.array([1.0, 2.0, 0.5])
    pelvis = np.tile([1.0, 2.0, 0.9], (T, 1))  # the axis through the ring's centre
    hem = np.arange(16)
    np.testing.assert_allclose(hem_flare(garment, pelvis, hem), radius)
    speed = hem_speed(garment, hem, 30.0)
    assert speed[0] == 0 and np.allclose(speed[1:], 0.01 * 30)


def test_hem_tilt_is_the_front_over_the_back_along_the_heading():
    angles = np.linspace(0, 2 * np.pi, 16, endpoint=False) + np.pi / 16  # none side-on
    ring = np.stack([np.cos(angles), np.sin(angles), np.zeros(16)], -1) * 0.4
    slope = 0.05 * np.arange(T)  # metres of height per metre along +Y, frame by frame
    garment = ring[None] + np.array([0.0, 0.0, 0.5])
    garment = np.repeat(garment, T, 0)
    garment[..., 2] += slope[:, None] * ring[None, :, 1]
    pelvis = np.tile([0.0, 0.0, 0.9], (T, 1))
    hem = np.arange(16)
    facing_y = np.tile([0.0, 1.0, -0.3], (T, 1))  # tipped down: only its heading counts
    tilt = hem_tilt(garment, pelvis, facing_y, hem)
    expected = slope * 2 * np.abs(ring[ring[:, 1] > 0, 1]).mean()  # front mean minus back mean
    np.testing.assert_allclose(tilt, expected, atol=1e-12)
    np.testing.assert_allclose(hem_tilt(garment, pelvis, -facing_y, hem), -expected, atol=1e-12)
    sideways = hem_tilt(garment, pelvis, np.tile([1.0, 0.0, 0.0], (T, 1)), hem)
    np.testing.assert_allclose(sideways, 0.0, atol=1e-12)
