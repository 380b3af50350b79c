"""The rollout loop: its later stages as a list, their chunks, overlap and feedback, the
hooks; the model protocols, construction from a checkpoint, the ONNX modules' imports."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys

import numpy as np
import pytest
import torch

import loosefit
from loosefit.api import motion_for
from loosefit.inference.animator import AnimationModel, collision_records
from loosefit.inference.baseline import BaselineModel
from loosefit.inference.protocols import AnimatingModel, BatchAnimatingModel, LearnedStages
from loosefit.inference.rollout import (
    RestartFromTruth,
    RolloutHooks,
    RolloutOptions,
    rollout,
)
from loosefit.inference.stages import MOTION_ONLY, StageClock, StageFrames, Stages, run_stages
from loosefit.model.baselines import BaselineConfig, BaselineNetwork
from tests.conftest import WITH_DETAIL
from tests.inference.conftest import tiny_model


class Lift:
    """A stage that lifts every garment by ``dz`` and remembers the runs it was given."""

    def __init__(self, name: str, dz: float) -> None:
        self.name, self.dz, self.calls = name, dz, []

    def __call__(self, frames: StageFrames) -> torch.Tensor:
        self.calls.append((frames.start, len(frames.vertices)))
        return frames.vertices + torch.tensor([0.0, 0.0, self.dz])


@pytest.fixture(scope="module")
def tiny(skirt, avatar):
    return tiny_model(skirt, avatar, "decomposed", previous_state=True)


@pytest.fixture(scope="module")
def motion(tiny):
    return motion_for("sway", tiny.avatar(), tiny.fps, 11)


def test_the_stages_run_in_order_a_chunk_at_a_time_beside_or_after(tiny, motion):
    plain = rollout(tiny.motion_stage(), motion)
    assert plain.decoded is None and set(plain.stage_seconds) == {"motion"}
    results = {}
    for overlap in (False, True):
        a, b = Lift("detail", 0.01), Lift("lengths", 0.02)
        options = RolloutOptions([a, b], overlap=overlap, chunk=4)
        results[overlap] = rollout(tiny.motion_stage(), motion, options)
        assert a.calls == b.calls == [(0, 4), (4, 4), (8, 3)]
        assert list(results[overlap].stage_seconds) == ["motion", "detail", "lengths"]
    np.testing.assert_array_equal(results[True].vertices, results[False].vertices)
    np.testing.assert_array_equal(results[True].decoded, plain.vertices)
    np.testing.assert_allclose(results[True].vertices, plain.vertices + [0, 0, 0.03], atol=1e-6)


def test_feedback_runs_the_stages_frame_by_frame_into_the_next_state(tiny, motion):
    lift = Lift("detail", 0.05)
    fed = rollout(tiny.motion_stage(), motion, RolloutOptions([lift], feedback=True))
    assert lift.calls == [(t, 1) for t in range(motion.num_frames)]
    after = rollout(tiny.motion_stage(), motion, RolloutOptions([Lift("detail", 0.05)]))
    np.testing.assert_allclose(fed.vertices[0], after.vertices[0], atol=1e-6)
    assert not np.allclose(fed.vertices[1:], after.vertices[1:], atol=1e-6)  # fed back


def test_hooks_see_every_frame_and_restart_from_the_truth(tiny, motion):
    seen = []
    clock = StageClock()
    hooks = RolloutHooks(progress=lambda done, total: seen.append((done, total)), clock=clock)
    free = rollout(tiny.motion_stage(), motion, hooks=hooks)
    assert seen[-1] == (free.frames, free.frames) and len(seen) == free.frames
    assert clock.seconds["motion"] > 0
    # restarted every frame from the free rollout's own garments: the same rollout
    shape = free.vertices.shape
    restart = RestartFromTruth(free.vertices, 1, shape, tiny.device)
    again = rollout(tiny.motion_stage(), motion, hooks=RolloutHooks(restart=restart))
    np.testing.assert_allclose(again.vertices, free.vertices, atol=1e-5)
    # restarted from a garment 1 cm higher: the next frame moves with it
    lifted = RestartFromTruth(free.vertices + [0, 0, 0.01], 5, shape, tiny.device)
    moved = rollout(tiny.motion_stage(), motion, hooks=RolloutHooks(restart=lifted))
    np.testing.assert_array_equal(moved.vertices[:5], free.vertices[:5])
    assert not np.allclose(moved.vertices[5], free.vertices[5], atol=1e-6)
    with pytest.raises(ValueError, match="truth: expected"):
        RestartFromTruth(free.vertices[1:], 1, shape, tiny.device)


def test_run_stages_leaves_its_input_as_it_was():
    x = torch.zeros(2, 3, 3)
    frames = StageFrames(x, torch.zeros(2, 4), torch.eye(3).expand(2, 3, 3), torch.zeros(2, 3), 0)
    out = run_stages([Lift("detail", 1.0)], frames)
    assert torch.equal(x, torch.zeros(2, 3, 3)) and torch.equal(out[..., 2], torch.ones(2, 3))


def test_the_animation_model_builds_its_later_stages(tiny, motion):
    later = tiny.later_stages(motion, Stages(), None)
    assert [s.name for s in later] == ["lengths", "collision"]
    assert [s.name for s in tiny.later_stages(motion, MOTION_ONLY, None)] == []
    result = rollout(tiny.motion_stage(), motion, RolloutOptions(later))
    records = collision_records(later)
    assert len(records) == motion.num_frames and "depth_after" in records[0]
    np.testing.assert_array_equal(result.vertices, tiny.animate(motion).vertices)


def test_models_are_told_apart_by_their_protocols(tiny):
    V = tiny.template.num_vertices
    net = BaselineNetwork(
        BaselineConfig(method="virtual-bones", motion_fc=8, gru=8, head_hidden=8),
        tiny.encoder.num_features,
        torch.zeros(V, 3),
        torch.zeros(V, 4),
    )
    fields = ("template", "joint_names", "floor_height", "fps", "body", "rollout_config", "path")
    baseline = BaselineModel(network=net, **{k: getattr(tiny, k) for k in fields})
    assert isinstance(tiny, AnimatingModel) and isinstance(baseline, AnimatingModel)
    assert isinstance(tiny, BatchAnimatingModel) and not isinstance(baseline, BatchAnimatingModel)
    assert isinstance(tiny, LearnedStages) and not isinstance(baseline, LearnedStages)
    with pytest.raises(TypeError):  # keyword-only
        AnimationModel(*(getattr(tiny, f.name) for f in dataclasses.fields(tiny)[:10]))


def test_from_checkpoint_is_what_loosefit_load_gives():
    model = AnimationModel.from_checkpoint(WITH_DETAIL / "motion.pt")
    assert model.detail is not None  # the packaged detail.pt beside it
    other = loosefit.load(WITH_DETAIL / "motion.pt").model
    assert type(other) is AnimationModel
    mine, theirs = model.encoder.state_dict(), other.encoder.state_dict()
    assert all(torch.equal(mine[k], theirs[k]) for k in mine)


def test_the_onnx_modules_do_not_import_the_animator():
    code = (
        "import json, sys\nimport loosefit.inference.onnx.stages\n"
        "print(json.dumps(sorted(sys.modules)))\n"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert "loosefit.inference.animator" not in json.loads(run.stdout.splitlines()[-1])
