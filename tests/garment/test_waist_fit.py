"""The waist ellipse and hip profile fitted to a synthetic body of known measures."""

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.garment.waist_fit import (
    WaistFit,
    hip_profile_from_points,
    profile_radii,
    waist_fit_from_points,
)

WAIST_Z = 1.0


def synthetic_body() -> np.ndarray:
    """(Vb, 3) a body-like point cloud: an elliptical torso, 0.16 x 0.11 at the waist (z = 1)
    and 0.19 x 0.13 at the hips (z = 0.9), on two leg cylinders centred at x = +-0.09."""
    angles = np.linspace(0, 2 * np.pi, 96, endpoint=False)
    parts = []
    for z in np.arange(0.78, 1.35, 0.005):
        rx = np.interp(z, [0.78, 0.9, 1.0, 1.2, 1.35], [0.17, 0.19, 0.16, 0.17, 0.15])
        ry = np.interp(z, [0.78, 0.9, 1.0, 1.2, 1.35], [0.12, 0.13, 0.11, 0.12, 0.11])
        parts.append(np.stack([rx * np.cos(angles), ry * np.sin(angles), np.full(96, z)], 1))
    for z in np.arange(0.0, 0.85, 0.005):
        r = np.interp(z, [0.0, 0.5, 0.85], [0.05, 0.065, 0.085])
        for x in (-0.09, 0.09):
            parts.append(np.stack([x + r * np.cos(angles), r * np.sin(angles), np.full(96, z)], 1))
    return np.concatenate(parts)


def ellipse_scale(xy: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """(N,) sqrt((x/rx)^2 + (y/ry)^2): < 1 inside the ellipse."""
    return np.sqrt(((xy / radii) ** 2).sum(axis=-1))


def profile_at(profile: np.ndarray, z: np.ndarray) -> np.ndarray:
    """(N, 2) interpolated profile radii, NaN outside its heights."""
    rows = profile[np.argsort(profile[:, 0])]
    return np.stack(
        [np.interp(z, rows[:, 0], rows[:, k], left=np.nan, right=np.nan) for k in (1, 2)], -1
    )


@pytest.fixture(scope="module")
def body() -> np.ndarray:
    return synthetic_body()


@pytest.fixture(scope="module")
def waist(body: np.ndarray) -> WaistFit:
    return waist_fit_from_points(body, WAIST_Z, profile_depth=0.6)


def test_waist_fit_recovers_the_waist_ellipse(waist: WaistFit) -> None:
    np.testing.assert_allclose(waist.center, [0.0, 0.0, WAIST_Z], atol=1e-3)
    # the slab (+-1.5 cm) reaches where the body widens towards the hips and chest
    assert (waist.radii >= [0.16, 0.11]).all() and (waist.radii <= [0.166, 0.116]).all()
    assert waist.height == WAIST_Z


def test_hip_profile_contains_the_body(body: np.ndarray) -> None:
    profile = hip_profile_from_points(body, WAIST_Z, 0.4, center=np.zeros(2))
    assert profile.shape[1] == 3 and np.all(np.diff(profile[:, 0]) < 0)
    inside = body[(body[:, 2] <= WAIST_Z) & (body[:, 2] >= 0.4)]
    scale = ellipse_scale(inside[:, :2], profile_at(profile, inside[:, 2]))
    assert scale.max() <= 1 + 1e-9
    hips = profile[np.argmin(np.abs(profile[:, 0] - 0.9))]
    assert hips[1] == pytest.approx(0.19, abs=0.01) and hips[2] == pytest.approx(0.13, abs=0.01)


def test_max_radius_drops_far_points(body: np.ndarray) -> None:
    hand = np.array([[0.45, 0.0, 0.9], [-0.45, 0.0, 0.9]])
    with_hands = np.concatenate([body, hand])
    loose = hip_profile_from_points(with_hands, WAIST_Z, 0.5, 11, center=np.zeros(2))
    tight = hip_profile_from_points(with_hands, WAIST_Z, 0.5, 11, max_radius=0.3)
    assert loose[:, 1].max() > 0.44 and tight[:, 1].max() < 0.25


def test_fit_errors_name_the_field(body: np.ndarray) -> None:
    with pytest.raises(LoosefitInputError, match="points"):
        waist_fit_from_points(body, 3.0)
    with pytest.raises(LoosefitInputError, match="z_bottom"):
        hip_profile_from_points(body, 0.5, 0.9)
    with pytest.raises(LoosefitInputError, match="radii"):
        WaistFit(center=[0, 0, 1], radii=[0.1, -0.1], height=1.0)
    with pytest.raises(LoosefitInputError, match="profile"):
        WaistFit(center=[0, 0, 1], radii=[0.1, 0.1], height=1.0, profile=[[1.0, 0.1]])


def test_profile_radii_interpolate_rows_and_call_a_function() -> None:
    rows = np.array([[0.9, 0.2, 0.1], [1.0, 0.1, 0.3]])
    z = np.array([0.8, 0.9, 0.95, 1.0, 1.1])
    want = np.array([[np.nan, np.nan], [0.2, 0.1], [0.15, 0.2], [0.1, 0.3], [np.nan, np.nan]])
    np.testing.assert_allclose(profile_radii(rows, z), want)
    called = profile_radii(lambda zk: (zk, 2 * zk) if zk < 1 else None, z)
    np.testing.assert_allclose(called, [[0.8, 1.6], [0.9, 1.8], [0.95, 1.9]] + [[np.nan] * 2] * 2)
    assert np.isnan(profile_radii(None, z)).all()
