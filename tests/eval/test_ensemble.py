"""Dynamics against an ensemble: the measures' properties on toy samples, and the scoring's
refusal of a clip with a single member."""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.eval import ensemble as en
from loosefit.eval.metrics import rmse_per_frame
from tests.eval.test_ensemble_members import _dataset, _sequence

T, V, J = 12, 40, 3


def _gaussian(rng, centre: np.ndarray, sigma: float, n: int) -> np.ndarray:
    return centre[None] + sigma * rng.normal(size=(n, *centre.shape))


def test_energy_score_rewards_the_right_spread_and_not_a_mean():
    """A proper score: samples drawn as the members are beat the members' mean, and samples
    too narrow or too wide; RMSE to the members would rank the mean first."""
    rng = np.random.default_rng(0)
    centre = rng.normal(size=(T, V, 3))
    members = _gaussian(rng, centre, 0.05, 8)
    right = _gaussian(rng, centre, 0.05, 8)
    narrow = _gaussian(rng, centre, 0.01, 8)
    wide = _gaussian(rng, centre, 0.2, 8)
    mean = members.mean(0)[None]
    score = {
        k: en.energy_score(x, members).mean()
        for k, x in (("right", right), ("narrow", narrow), ("wide", wide), ("mean", mean))
    }
    assert score["right"] < score["mean"]
    assert score["right"] < score["narrow"] and score["right"] < score["wide"]
    # RMSE to the members prefers the mean: why the energy score is reported
    assert (
        en.rmse_to_members(mean[0], members).mean() < en.rmse_to_members(right[0], members).mean()
    )


def test_energy_score_of_one_sample_is_its_mean_distance():
    rng = np.random.default_rng(1)
    x, members = rng.normal(size=(1, T, V, 3)), rng.normal(size=(3, T, V, 3))
    want = np.mean([rmse_per_frame(x[0], m) for m in members], axis=0)
    np.testing.assert_allclose(en.energy_score(x, members), want)
    # the members' own score: each against the others as samples
    own = en.members_energy_score(members)
    assert own.shape == (T,) and np.all(own > 0)


def test_a_spread_of_one_member_is_refused_with_how_to_make_more():
    with pytest.raises(LoosefitInputError, match="--seeds"):
        en.pairwise_rmse(np.zeros((1, T, V, 3)))
    with pytest.raises(LoosefitInputError, match="three members"):
        en.members_energy_score(np.zeros((2, T, V, 3)))


def test_pairwise_spread_and_rmse_to_the_mean():
    a = np.zeros((T, V, 3))
    b = a + np.array([0.03, 0.0, 0.0])
    c = a + np.array([0.0, 0.04, 0.0])
    pairs = en.pairwise_rmse(np.stack([a, b, c]))
    np.testing.assert_allclose(pairs[:, 0], [0.03, 0.04, 0.05])
    np.testing.assert_allclose(en.rmse_to_mean(a, np.stack([b, -b])), 0.0, atol=1e-12)


def test_band_and_turn_window():
    radius = 0.2 + 0.01 * np.arange(T)
    band = np.stack([radius - 0.01, radius + 0.01])
    inside = en.inside_band(radius + np.where(np.arange(T) < 3, 0.05, 0.0), band)
    assert inside.tolist() == [False] * 3 + [True] * (T - 3)
    w = en.turn_window(5, T, half=3)
    assert (w.start, w.stop) == (2, 9)
    assert (en.turn_window(1, 100).start, en.turn_window(99, 100).stop) == (0, 100)


def test_band_gap_is_the_distance_outside_the_members_range():
    band = np.array([[0.30, 0.30, 0.30, 0.30], [0.32, 0.34, 0.32, 0.32]])  # (M=2, T=4)
    series = np.array([0.31, 0.25, 0.40, 0.32])
    np.testing.assert_allclose(en.band_gap(series, band), [0.0, 0.05, 0.08, 0.0], atol=1e-12)
    assert (en.band_gap(series, band) == 0).tolist() == en.inside_band(series, band).tolist()


def _cylinder(radius: float, z0: float, z1: float, n: int = 24):
    """An open tube about +Z (a skirt) as vertices and triangles."""
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = np.stack([np.cos(a), np.sin(a)], -1) * radius
    v = np.concatenate([np.c_[ring, np.full(n, z0)], np.c_[ring, np.full(n, z1)]])
    i = np.arange(n)
    j = (i + 1) % n
    f = np.concatenate([np.stack([i, j, n + i], -1), np.stack([j, n + j, n + i], -1)])
    return v, f


def _box(centre, half: float):
    c = np.asarray(centre, float)
    v = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float) * half + c
    f = np.array(
        [
            [0, 1, 3],
            [0, 3, 2],
            [4, 6, 7],
            [4, 7, 5],
            [0, 4, 5],
            [0, 5, 1],
            [2, 3, 7],
            [2, 7, 6],
            [0, 2, 6],
            [0, 6, 4],
            [1, 5, 7],
            [1, 7, 3],
        ]
    )
    return v, f


def test_cloth_in_front_of_a_knee_under_the_skirt_and_not_of_one_through_it():
    skirt, skirt_faces = _cylinder(0.35, 0.3, 0.8)
    pelvis = np.array([0.0, 0.0, 0.9])
    covered = np.array([0.2, 0.0, 0.55])  # 20 cm out, the skirt at 35 cm
    body, body_faces = _box(covered, 0.05)
    assert en.cloth_in_front(covered, pelvis, skirt, skirt_faces, body, body_faces)
    through = np.array([0.33, 0.0, 0.55])  # the knee's skin (5 cm round) beyond the cloth
    body, body_faces = _box(through, 0.05)
    assert not en.cloth_in_front(through, pelvis, skirt, skirt_faces, body, body_faces)
    above = np.array([0.2, 0.0, 0.95])  # over the waist: no cloth on the ray
    body, body_faces = _box(above, 0.05)
    assert not en.cloth_in_front(above, pelvis, skirt, skirt_faces, body, body_faces)


def test_raised_knees_are_frames_with_one_knee_up_and_under_the_pelvis():
    knees = np.zeros((4, 2, 3))
    knees[:, :, 2] = 0.5
    knees[1, 0, 2] = 0.65  # left up 15 cm
    knees[2, 1, 2] = 1.1  # right up over the pelvis: not under the skirt
    knees[3, 1, 2] = 0.55  # 5 cm: not raised
    pelvis = np.tile([0.0, 0.0, 0.9], (4, 1))
    frames, which = en.raised_knees(knees, pelvis)
    assert frames.tolist() == [1] and which.tolist() == [0]


def test_scoring_without_a_second_member_says_how_to_make_one(tmp_path):
    corpus = _dataset(tmp_path / "corpus", 0, {"c": _sequence(6, 0.0)})
    with pytest.raises(LoosefitInputError, match="--seeds"):
        en.evaluate_ensemble({}, [corpus])
