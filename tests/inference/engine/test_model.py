"""The shipped engine tier's rollout (loosefit.inference.engine.model) on the demo's moves."""

import numpy as np
import pytest
import torch

from loosefit.inference.engine.model import engine_path_of, load_engine, rollout_engine


@pytest.fixture(scope="module")
def shipped():
    from loosefit.api import pretrained_checkpoint

    return load_engine(engine_path_of(pretrained_checkpoint()))


def waist_radius(garments: np.ndarray, waist: np.ndarray) -> np.ndarray:
    """(T,) the mean XY distance of the waistband's vertices from their centroid."""
    ring = garments[:, waist]  # (T, W, 3)
    return np.linalg.norm((ring - ring.mean(1, keepdims=True))[..., :2], axis=-1).mean(1)


def test_the_waistband_holds_the_waist_on_a_procedural_dance(shipped, avatar):
    from loosefit.body.capsules import avatar_capsules
    from loosefit.inference.engine.export import EngineStep, skeleton_record
    from loosefit.motion.motions import load_motion

    motion = load_motion("dance:2", avatar, fps=shipped.fps, seed=0)
    step = EngineStep(shipped, avatar_capsules(avatar), skeleton_record(avatar)).eval()
    x = rollout_engine(shipped, motion, collide=step)  # (T, V, 3)
    waist = shipped.template.waist
    with torch.no_grad():
        rest = shipped.tier.decode(shipped.tier.rest[None]).numpy()  # (1, V, 3) settled drape
    r, r_rest = waist_radius(x, waist), waist_radius(rest, waist)[0]
    assert 0.09 < r_rest < 0.12  # the band on the waist, as simulated (10.5 cm)
    # pushed out of the waist's capsule with the rest, the band stood 4-5 cm loose
    assert np.abs(r - r_rest).max() < 0.01
