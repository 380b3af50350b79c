"""10,000 frames in one rollout of the packaged model: finite, on the body, and not drifting
(``pytest -m slow``; the figure against the simulation: bench/quality/long_rollout.py)."""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.inference.stages import MOTION_ONLY
from loosefit.model.motion_features import garment_in_root_frame
from loosefit.motion.chain import chain_motions


@pytest.mark.slow
def test_ten_thousand_frames_stay_on_the_body_and_repeat_themselves():
    import loosefit

    model = loosefit.load()
    clip = loosefit.api.motion_for("dance:20", model.model.avatar(), model.fps, seed=3)
    repeats = -(-10_000 // clip.num_frames)  # blends add frames: at least 10,000
    chain = chain_motions([clip] * repeats)
    assert chain.num_frames >= 10_000
    g = model.model.animate(chain, stages=MOTION_ONLY).vertices  # (T, V, 3)
    assert np.isfinite(g).all()
    assert np.linalg.norm(g - chain.root_translation[:, None], axis=-1).max() < 1.5
    # the same dance again and again: each repetition close to the second (the first starts
    # from rest), and no closer to drifting at the end than near the start
    reps = [
        garment_in_root_frame(chain.slice(f, f + n), g[f : f + n]).numpy()
        for _, f, n in chain.meta["segments"]
    ]
    diff = [100 * np.sqrt(((r - reps[1]) ** 2).sum(-1).mean()) for r in reps[2:]]  # cm
    assert max(diff) < 10.0, diff
    assert np.mean(diff[-3:]) <= np.mean(diff[:3]) + 1.0, diff
