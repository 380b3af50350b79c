"""What a model that animates offers: ours, the engine tier (and the baselines, in
tests/train/test_baseline.py) are AnimatingModels; only ours animates N motions at once and
has learned stages to export."""

from __future__ import annotations

import pytest

import loosefit
from loosefit.inference.protocols import AnimatingModel, BatchAnimatingModel, LearnedStages
from tests.conftest import REPO

PAIR = REPO / "checkpoints" / "dance"


@pytest.fixture(scope="module")
def ours():
    return loosefit.load(PAIR / "motion.pt").model


@pytest.fixture(scope="module")
def engine():
    return loosefit.load(PAIR / "engine.pt").model


def test_ours_is_every_protocol(ours):
    assert isinstance(ours, AnimatingModel)
    assert isinstance(ours, BatchAnimatingModel)
    assert isinstance(ours, LearnedStages)


def test_the_engine_tier_animates_but_not_in_batches_nor_as_learned_stages(engine):
    assert isinstance(engine, AnimatingModel)
    assert not isinstance(engine, BatchAnimatingModel)
    assert not isinstance(engine, LearnedStages)


def test_an_object_without_animate_is_no_animating_model(ours):
    class Frozen:
        template, joint_names, fps, floor_height = ours.template, ours.joint_names, 30.0, 0.9
        body, rollout_config, path, stages = {}, ours.rollout_config, PAIR, ours.stages

        def avatar(self):
            return None

        def check_motion(self, motion):
            return None

    assert not isinstance(Frozen(), AnimatingModel)
    Frozen.animate = lambda self, motion, progress=None: None
    assert isinstance(Frozen(), AnimatingModel)


def test_a_batch_of_the_engine_tier_is_refused_by_the_api():
    from loosefit.errors import LoosefitInputError

    with pytest.raises(LoosefitInputError, match="one motion at a time"):
        loosefit.load(PAIR / "engine.pt").animate_batch(["sway"], frames=2)
