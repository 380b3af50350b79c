"""Fitting a motion stage's residual process, and its realisations through a rollout."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from loosefit.data.format import DatasetReader
from loosefit.errors import LoosefitInputError
from loosefit.inference.checkpoints import save_atomic
from loosefit.inference.residual import attach_residual, residual_record
from loosefit.inference.stages import MOTION_ONLY
from loosefit.model.motion_features import from_root_frame
from loosefit.model.residual import ResidualConfig, residual_offsets
from loosefit.train.residual import clip_residuals, fit_residual
from tests.inference.conftest import tiny_model


@pytest.fixture(scope="module")
def model(skirt, avatar):
    return tiny_model(skirt, avatar, "decomposed", previous_state=True)


@pytest.fixture(scope="module")
def fitted(model, toy_dataset):
    return fit_residual(model, toy_dataset, ResidualConfig(4, 0.9, 1.0), log=lambda *_: None)


def test_the_fit_reads_every_training_frame(model, toy_dataset, fitted):
    process, record = fitted
    reader = DatasetReader(toy_dataset)
    frames = sum(reader.read(c).num_frames for c in reader.split("train"))
    assert record["clips"] == reader.split("train") and record["frames"] == frames
    assert process.basis.shape == (4, model.template.num_vertices, 3)
    # the residual is the simulation less the rollout, in the root frame
    seq = reader.read("a")
    r = clip_residuals(model, seq)
    rolled = model.animate(seq.motion, stages=MOTION_ONLY).vertices
    _, H, p, P = model.motion_stage().inputs(seq.motion)
    back = from_root_frame(r, H[P:], torch.zeros_like(p[P:])).numpy()
    np.testing.assert_allclose(back, seq.garment_vertices - rolled, atol=1e-5)
    assert record["residual_rms"] > 0 and torch.isfinite(process.std).all()


def test_a_realisation_adds_its_offsets_and_never_feeds_them_back(model, toy_dataset, fitted):
    process, _ = fitted
    motion = DatasetReader(toy_dataset).read("c").motion
    model.residual = process.with_scale(2.0)
    try:
        plain = model.animate(motion, stages=MOTION_ONLY).vertices
        a = model.animate(motion, stages=MOTION_ONLY, realisation=5).vertices
        b = model.animate(motion, stages=MOTION_ONLY, realisation=5).vertices
        c = model.animate(motion, stages=MOTION_ONLY, realisation=6).vertices
        none = model.animate(motion, stages=MOTION_ONLY, realisation=None).vertices
    finally:
        model.residual = None
    np.testing.assert_array_equal(a, b)  # a seed's realisation, every run
    np.testing.assert_array_equal(none, plain)
    assert np.abs(a - c).max() > 1e-4
    # exactly the offsets, turned with each frame's heading: the dynamics are untouched
    _, H, p, P = model.motion_stage().inputs(motion)
    off = residual_offsets(process.with_scale(2.0), motion.num_frames, 5)
    want = from_root_frame(off, H[P:], torch.zeros_like(p[P:])).numpy()
    np.testing.assert_allclose(a - plain, want, atol=1e-5)


def test_the_record_attaches_to_its_own_stages_only(model, skirt, avatar, fitted, tmp_path):
    process, record = fitted
    path = tmp_path / "residual.pt"
    save_atomic(residual_record(model, process, record), path)
    other = tiny_model(skirt, avatar, "decomposed", previous_state=True)
    attach_residual(other, path)
    assert other.residual.config == process.config
    torch.manual_seed(1)
    changed = tiny_model(skirt, avatar, "decomposed", previous_state=False)
    with pytest.raises(LoosefitInputError, match="fingerprints.motion"):
        attach_residual(changed, path)


def test_a_realisation_of_a_model_without_a_process_is_refused(model, toy_dataset):
    motion = DatasetReader(toy_dataset).read("c").motion
    model.residual = None
    with pytest.raises(LoosefitInputError, match="residual"):
        model.animate(motion, realisation=0)


def test_too_few_frames_for_the_directions_are_refused(model, toy_dataset):
    with pytest.raises(LoosefitInputError, match="frames"):
        fit_residual(model, toy_dataset, ResidualConfig(directions=500), log=lambda *_: None)


def test_evaluate_scores_a_set_by_its_realisations(model, toy_dataset, fitted, tmp_path):
    """``loosefit evaluate --members ... --realisations S``: a set with a residual process is
    scored by S realisations (the energy score with their spread), another by its one
    garment."""
    from loosefit.eval.ensemble import evaluate_ensemble
    from tests.train.conftest import toy_member

    seed1, _ = toy_member(toy_dataset, tmp_path / "seed1")
    process, _ = fitted
    model.residual = process.with_scale(2.0)
    try:
        many = evaluate_ensemble({"ours": model}, [toy_dataset, seed1], surface=False,
                                 realisations=3)  # fmt: skip
        one = evaluate_ensemble({"ours": model}, [toy_dataset, seed1], surface=False)
    finally:
        model.residual = None
    a, b = many["clips"]["c"]["models"]["ours"], one["clips"]["c"]["models"]["ours"]
    assert a["samples"] == 3 and b["samples"] == 1
    assert a["energy_score_cm"] != b["energy_score_cm"]


def test_the_gain_is_fitted_on_clips_not_trained_on_and_scales_a_realisation(model, toy_dataset):
    from loosefit.model.residual import motion_intensity

    process, record = fit_residual(
        model, toy_dataset, ResidualConfig(4, 0.9, 1.0), gain_clips=["c"], log=lambda *_: None
    )
    fit = record["gain"]
    assert fit["clips"] == ["c"] and fit["frames"] == 16 and np.isfinite(fit["correlation"])
    assert process.gain != (1.0, 0.0) and all(np.isfinite(process.gain))
    motion = DatasetReader(toy_dataset).read("c").motion
    model.residual = process
    try:
        plain = model.animate(motion, stages=MOTION_ONLY).vertices
        drawn = model.animate(motion, stages=MOTION_ONLY, realisation=1).vertices
    finally:
        model.residual = None
    w = motion_intensity(motion.rotations, motion.fps)
    off = residual_offsets(process, motion.num_frames, 1, w)
    _, H, p, P = model.motion_stage().inputs(motion)
    want = from_root_frame(off, H[P:], torch.zeros_like(p[P:])).numpy()
    np.testing.assert_allclose(drawn - plain, want, atol=1e-5)
