"""The engine tier's training clips (loosefit.train.engine): the demo's procedural moves."""

from __future__ import annotations

import numpy as np
import pytest

import loosefit
from loosefit.errors import LoosefitInputError
from loosefit.train.engine import PROCEDURAL_SEED, TrainEngineConfig, procedural_clips


@pytest.mark.slow  # the pretrained set and its avatar: 1-2 minutes on a shared 2-core machine
def test_procedural_clips_are_the_full_models_rollouts_in_the_root_frame():
    from loosefit.api import pretrained_checkpoint
    from loosefit.inference.stages import MOTION_ONLY
    from loosefit.model.motion_features import from_root_frame
    from loosefit.motion.motions import load_motion

    full = loosefit.load(pretrained_checkpoint()).model
    config = TrainEngineConfig(procedural=1, procedural_seconds=1)
    floor = float(full.floor_height)
    (clip,) = procedural_clips(full, config, floor, 30.0)
    motion = load_motion("dance:1", full.avatar(), fps=30.0, seed=PROCEDURAL_SEED)
    T, P = motion.num_frames, clip.preroll
    assert clip.name == f"dance_{PROCEDURAL_SEED}" and clip.target.shape == (T, 2352, 3)
    assert clip.features.shape[0] == P + T and clip.heading.shape == (P + T, 3, 3)
    world = full.animate(motion, stages=MOTION_ONLY).vertices
    back = from_root_frame(clip.target, clip.heading[P:], clip.origin[P:]).numpy()
    np.testing.assert_allclose(back, world, atol=1e-4)
    assert procedural_clips(full, TrainEngineConfig(), floor, 30.0) == []


def test_a_negative_count_of_procedural_dances_is_refused():
    with pytest.raises(LoosefitInputError, match="procedural"):
        TrainEngineConfig(procedural=-1).validate()
