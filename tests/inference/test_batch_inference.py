"""N characters at once: the batched rollout gives each motion the garment
its own rollout gives."""

from __future__ import annotations

import numpy as np
import pytest

import loosefit
from loosefit.errors import LoosefitInputError
from loosefit.inference.stages import MOTION_ONLY, Stages


@pytest.fixture(scope="module")
def model():
    return loosefit.load()


def test_a_batch_of_motions_animates_each_as_alone(model):
    avatar = model.model.avatar()
    motions = [
        loosefit.api.motion_for(spec, avatar, model.fps, frames)
        for spec, frames in (("sway", 40), ("spin", 25), ("kick", 33))
    ]
    for stages in (MOTION_ONLY, Stages()):  # the motion stage; then detail and collision too
        batch = model.model.animate_batch(motions, stages=stages)
        for m, b in zip(motions, batch, strict=True):
            alone = model.model.animate(m, stages=stages)
            assert b.vertices.shape == (m.num_frames, model.template.num_vertices, 3)
            if not stages.collision:
                np.testing.assert_allclose(b.vertices, alone.vertices, atol=2e-4)
            else:  # its thresholds (inside or not, an edge over its limit) can turn the
                # motion stage's float rounding into a sub-millimetre move of a few vertices
                off = np.abs(np.asarray(b.vertices) - np.asarray(alone.vertices)).max(-1)
                assert (off > 2e-4).mean() < 1e-3 and off.max() < 2e-3
                assert len(b.collisions) == m.num_frames


def test_the_api_animates_a_list(model, avatar):
    results = model.animate_batch(["sway", "dance:2"], frames=12)
    assert [r.num_frames for r in results] == [12, 12]
    assert results[1].motion.name != results[0].motion.name
    assert all(np.isfinite(r.vertices).all() for r in results)
    other = avatar.rest_motion(5)
    other.fps = 60.0
    with pytest.raises(LoosefitInputError, match="fps"):
        model.animate_batch([other])


def test_a_diverging_batch_names_the_motion(model):
    import dataclasses

    from loosefit.inference.rollout import RolloutError, rollout_batch

    m = model.model
    motions = [loosefit.api.motion_for(s, m.avatar(), model.fps, 5) for s in ("sway", "spin")]
    tight = dataclasses.replace(m.rollout_config, max_distance=0.3)  # the skirt's hem is further
    with pytest.raises(RolloutError, match=r"preroll frame 0 of motion 0 \('sway'\).*0\.3 m"):
        rollout_batch(dataclasses.replace(m.motion_stage(), config=tight), motions)
