"""The reference step loop on a hand-made graph of the exported interface: the JSON read and
checked, one step for B characters with their state, a rollout over the timeline, and the
refusals of motions the graph was not made for."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.inference.onnx.runtime import (
    FORMAT,
    OnnxDivergedError,
    OnnxRuntime,
    check_diverged,
    read_metadata,
    rollout_onnx,
)
from loosefit.inference.timeline import rollout_timeline
from tests.inference.conftest import needs_ort
from tests.inference.onnx.graph import JOINTS, OFFSETS, walk, write_step_graph

pytestmark = needs_ort


@pytest.fixture
def graph(tmp_path):
    return write_step_graph(tmp_path / "step.onnx", FORMAT)


def test_one_step_for_two_characters_carries_each_one_s_state(graph):
    runtime = OnnxRuntime(graph)
    assert runtime.joint_names == JOINTS and runtime.fps == 30.0
    state = runtime.initial_state(2)
    assert list(state) == ["frames_in"] and state["frames_in"].shape == (2, 1)
    rot = np.tile(np.eye(3, dtype=np.float32), (2, 3, 1, 1))
    root = np.array([[0.0, 0.0, 1.0], [2.0, 1.0, 0.9]], np.float32)
    for _ in range(3):
        garment, state = runtime.step(rot, root, state)
    np.testing.assert_allclose(garment, root[:, None] + OFFSETS, atol=1e-7)
    np.testing.assert_array_equal(state["frames_in"][:, 0], [3, 3])
    _, state = runtime.step(rot, root, state, start=np.array([True, False]))
    np.testing.assert_array_equal(state["frames_in"][:, 0], [1, 4])  # the first starts over


def test_a_rollout_runs_the_timeline_and_returns_the_motion_s_frames(graph):
    motion = walk(T=5)
    calls = []
    out = rollout_onnx(OnnxRuntime(graph), motion, progress=lambda d, t: calls.append((d, t)))
    assert out.shape == (5, 3, 3) and out.dtype == np.float32
    np.testing.assert_allclose(out, motion.root_translation[:, None] + OFFSETS, atol=1e-6)
    _, _, P = rollout_timeline(motion, 0.9, 3, 0.1)
    assert calls == [(i, P + 5) for i in range(1, P + 6)]


def test_motions_the_graph_was_not_made_for_are_refused(graph):
    runtime = OnnxRuntime(graph)
    with pytest.raises(
        LoosefitInputError,
        match=r"motion 'walk': field 'joint_names': expected the graph's 3 joints",
    ):
        rollout_onnx(runtime, walk(joints=["Hips", "Head", "Spine"]))
    with pytest.raises(
        LoosefitInputError, match=r"field 'fps': expected 30, found 24 \(resample it\)"
    ):
        rollout_onnx(runtime, walk(fps=24.0))


def test_a_garment_far_from_its_root_is_a_divergence(tmp_path):
    runtime = OnnxRuntime(write_step_graph(tmp_path / "near.onnx", FORMAT, max_distance=0.5))
    with pytest.raises(
        OnnxDivergedError, match=r"rollout diverged at preroll frame 0: a vertex is 0\.61 m"
    ):
        rollout_onnx(runtime, walk())
    root = np.zeros((1, 3), np.float32)
    check_diverged(np.full((1, 2, 3), 0.5, np.float32), root, 1.0, "frame 2")  # 0.87 m: fine
    with pytest.raises(OnnxDivergedError, match="at frame 2"):
        check_diverged(np.full((1, 2, 3), np.nan, np.float32), root, 1.0, "frame 2")


def test_the_json_beside_the_graph_is_checked(graph, tmp_path):
    assert read_metadata(graph)["vertex_count"] == 3
    meta = json.loads(graph.with_suffix(".json").read_text())
    other = tmp_path / "other.json"
    other.write_text(json.dumps({**meta, "format": "something/2"}))
    with pytest.raises(
        LoosefitInputError,
        match=r"other\.json: field 'format': expected 'loosefit-onnx-step/1', found 'something/2'",
    ):
        read_metadata(graph, meta_path=other)
    other.write_text("{not json")
    with pytest.raises(LoosefitInputError, match=r"other\.json: field '<file>': expected JSON"):
        read_metadata(graph, meta_path=other)
    with pytest.raises(LoosefitInputError, match=r"nothing\.json: field '<file>'.*no such file"):
        read_metadata(tmp_path / "nothing.onnx")
    other.write_text(json.dumps({**meta, "inputs": {"joint_rotations": {}, "start": {}}}))
    with pytest.raises(LoosefitInputError, match=r"field 'inputs': expected the JSON's"):
        OnnxRuntime(graph, meta_path=other)
    with pytest.raises(
        LoosefitInputError, match=r"field '<file>': expected an exported \.onnx graph"
    ):
        OnnxRuntime(tmp_path / "missing.onnx")


def test_without_onnxruntime_the_error_says_how_to_install_it(graph, monkeypatch):
    monkeypatch.setitem(sys.modules, "onnxruntime", None)
    with pytest.raises(LoosefitInputError, match=r"onnxruntime \(pip install 'loosefit\[onnx\]'\)"):
        OnnxRuntime(graph)
