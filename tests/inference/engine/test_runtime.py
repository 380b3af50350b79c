"""The engine tier's reference loop on a hand-made graph of its interface: the skeleton
checked joint by joint, and a rollout over the timeline."""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.inference.engine.runtime import FORMAT, EngineRuntime, rollout_engine_onnx
from tests.inference.conftest import needs_ort
from tests.inference.onnx.graph import OFFSETS, walk, write_step_graph

pytestmark = needs_ort


@pytest.fixture
def runtime(tmp_path):
    return EngineRuntime(write_step_graph(tmp_path / "engine.onnx", FORMAT))


def test_a_skeleton_must_be_the_engine_s_joints_in_its_order(runtime):
    runtime.check_skeleton(["Hips", "Spine", "Head"])
    with pytest.raises(
        LoosefitInputError,
        match=r"rig: field 'joint_names\[1\]': expected 'Spine', found 'Head' "
        r"\(the 3 joints of engine\.json",
    ):
        runtime.check_skeleton(["Hips", "Head", "Spine"], "rig")
    with pytest.raises(
        LoosefitInputError, match=r"field 'joint_names\[2\]': expected 'Head', found no more joints"
    ):
        runtime.check_skeleton(["Hips", "Spine"])
    with pytest.raises(
        LoosefitInputError, match=r"field 'joint_names\[3\]': expected no more joints, found 'Tail'"
    ):
        runtime.check_skeleton(["Hips", "Spine", "Head", "Tail"])


def test_the_engine_s_rollout_returns_the_motion_s_frames(runtime):
    motion = walk(T=4)
    out = rollout_engine_onnx(runtime, motion)
    assert out.shape == (4, 3, 3) and out.dtype == np.float32
    np.testing.assert_allclose(out, motion.root_translation[:, None] + OFFSETS, atol=1e-6)
    with pytest.raises(
        LoosefitInputError, match=r"motion 'walk': field 'fps': expected 30, found 60"
    ):
        rollout_engine_onnx(runtime, walk(fps=60.0))
    with pytest.raises(LoosefitInputError, match=r"motion 'walk': field 'joint_names\[0\]'"):
        rollout_engine_onnx(runtime, walk(joints=["Root", "Spine", "Head"]))


def test_a_step_graph_s_json_is_not_an_engine_s(tmp_path):
    from loosefit.inference.onnx.runtime import FORMAT as STEP

    graph = write_step_graph(tmp_path / "step.onnx", STEP)
    with pytest.raises(
        LoosefitInputError,
        match=r"field 'format': expected 'loosefit-onnx-engine/1'.*export-model --tier engine",
    ):
        EngineRuntime(graph)
