"""A dress end to end at test size: simulated, both stages trained, an unseen motion animated
with the upper arms in its collider (the full-size run: scripts/dress_model.sh)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import loosefit
from loosefit.inference.timeline import RolloutConfig
from loosefit.model.generative import GenerativeConfig
from loosefit.model.motion_encoder import MotionEncoderConfig
from loosefit.sim.generate import generate
from loosefit.sim.presets import preset
from loosefit.train.generative import TrainGenerativeConfig, train_generative
from loosefit.train.motion import TrainMotionConfig, train_motion
from tests.train.conftest import SMALL

pytestmark = pytest.mark.heavy  # a dress data set simulated, then both stages trained


def test_a_dress_trains_and_animates_a_motion_it_never_saw(tmp_path, avatar):
    data = tmp_path / "dress"
    generate(preset("dress-tiny"), data, workers=1, progress=False)
    quiet = dict(log=lambda *_: None, progress=False)
    gcfg = TrainGenerativeConfig(
        model=GenerativeConfig(**SMALL),
        epochs=6,
        batch_size=8,
        lr=2e-3,
        eval_every=1000,
        checkpoint_every=3,
    )
    train_generative(data, tmp_path / "gen", gcfg, **quiet)
    mcfg = TrainMotionConfig(
        model=MotionEncoderConfig(motion_fc=16, gru=24),
        rollout=RolloutConfig(warm_frames=2, blend_seconds=0.1),
        epochs=3,
        batch_size=2,
        window=6,
        lr=3e-3,
        eval_every=1000,
    )
    report = train_motion(
        data,
        tmp_path / "gen" / "checkpoint.pt",
        tmp_path / "motion",
        dataclasses.replace(mcfg),
        **quiet,
    )
    assert np.isfinite(report["test"]["rmse_cm"])
    model = loosefit.load(tmp_path / "motion" / "model.pt")
    # as the data was simulated: the upper arms in the body, the forearms a mesh of their own
    assert model.model.arm_collision is True
    result = model.animate("sway", frames=20)  # not among the data's kick and spin
    assert result.template.meta["kind"] == "dress"
    assert result.vertices.shape == (20, result.template.num_vertices, 3)
    assert np.isfinite(result.vertices).all()
    # on the body: the top band stays round the chest, nothing flies off
    top = result.vertices[:, result.template.waist].mean(1)
    assert np.abs(top[:, 2] - top[0, 2]).max() < 0.1
    assert np.linalg.norm(result.vertices - top[:, None], axis=-1).max() < 1.5
