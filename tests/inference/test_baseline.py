"""A baseline's checkpoint as a model: another stage's checkpoint is refused, saying what it
is and what opens it. (Trained baselines, their rollouts and post-process:
tests/train/test_baseline.py.)"""

from __future__ import annotations

import pytest

from loosefit.errors import LoosefitInputError
from loosefit.inference.baseline import BaselineModel, load_baseline
from tests.conftest import REPO

PAIR = REPO / "checkpoints" / "dance"


def test_our_motion_stage_is_refused_with_the_loader_that_opens_it():
    with pytest.raises(LoosefitInputError) as err:
        BaselineModel.from_checkpoint(PAIR / "motion.pt")
    text = str(err.value)
    assert "'loosefit.baseline/1'" in text and "'loosefit.motion/1'" in text
    assert "open it with loosefit.load" in text


def test_the_engine_tier_is_refused_naming_it():
    with pytest.raises(LoosefitInputError, match="this is the engine tier's checkpoint"):
        load_baseline(PAIR / "engine.pt")


def test_contents_already_read_are_checked_as_a_file(tmp_path):
    from loosefit.inference.checkpoints import load_torch

    data = load_torch(PAIR / "generative.pt")
    with pytest.raises(LoosefitInputError, match="the generative stage's checkpoint"):
        BaselineModel.from_checkpoint(PAIR / "generative.pt", data=data)
    with pytest.raises(LoosefitInputError, match="no such file"):
        BaselineModel.from_checkpoint(tmp_path / "missing.pt")
