"""The paper's model from its checkpoints: a set's motion stage takes the detail stage beside
it, a detail checkpoint brings the motion stage it records, a detail stage of another motion
stage is refused, and contents already read load as the file does."""

from __future__ import annotations

import pytest
import torch

from loosefit.errors import LoosefitInputError
from loosefit.inference.animator import (
    AnimationModel,
    attach_detail,
    load_animation_model,
)
from loosefit.inference.checkpoints import load_torch, model_fingerprint, stage_fingerprints
from tests.conftest import REPO, WITH_DETAIL

PAIR = REPO / "checkpoints" / "dance"


@pytest.fixture(scope="module")
def salsa():
    return AnimationModel.from_checkpoint(WITH_DETAIL / "motion.pt")


def test_a_set_s_motion_stage_takes_the_detail_stage_beside_it(salsa):
    assert salsa.detail is not None
    alone = load_animation_model(WITH_DETAIL / "motion.pt")  # the motion stage only
    assert alone.detail is None
    assert model_fingerprint(alone.encoder) == model_fingerprint(salsa.encoder)


def test_a_detail_checkpoint_brings_the_motion_stage_it_records(salsa):
    model = AnimationModel.from_checkpoint(WITH_DETAIL / "detail.pt")
    assert stage_fingerprints(model) == stage_fingerprints(salsa)
    assert model_fingerprint(model.detail) == model_fingerprint(salsa.detail)


def test_contents_already_read_load_as_the_file(salsa):
    data = load_torch(WITH_DETAIL / "motion.pt")
    model = AnimationModel.from_checkpoint(WITH_DETAIL / "motion.pt", data=data)
    for a, b in zip(model.encoder.parameters(), salsa.encoder.parameters(), strict=True):
        assert torch.equal(a, b)
    with pytest.raises(LoosefitInputError, match="'loosefit.motion/1'"):
        load_animation_model(PAIR / "engine.pt", data=load_torch(PAIR / "engine.pt"))


def test_a_detail_stage_of_another_motion_stage_is_refused():
    dance = load_animation_model(PAIR / "motion.pt")
    with pytest.raises(LoosefitInputError, match="fingerprints.garment|fingerprints.motion"):
        attach_detail(dance, WITH_DETAIL / "detail.pt")
    assert dance.detail is None
