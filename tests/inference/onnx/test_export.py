"""The ONNX export: onnxruntime rolls out PyTorch's frames; the JSON says
what the inputs are; stages the graph cannot hold are refused by name."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest
import torch

import loosefit
from loosefit.api import motion_for
from loosefit.errors import LoosefitInputError
from loosefit.inference.onnx.export import (
    INPUTS,
    OUTPUTS,
    STATE,
    OnnxExportConfig,
    check_exportable,
    export_onnx,
)
from loosefit.inference.onnx.runtime import OnnxRuntime, rollout_onnx
from loosefit.inference.stages import MOTION_ONLY, Stages
from tests.inference.conftest import needs_ort, tiny_baseline, tiny_model

DETAIL_ONLY = Stages(lengths=False, collision=False, overlap=False)  # what the graph holds


@pytest.fixture(scope="module")
def exported(model, tmp_path_factory):
    path = tmp_path_factory.mktemp("onnx") / "salsa.onnx"
    model.export_onnx(path)
    return path


@needs_ort
def test_onnxruntime_rolls_out_the_pytorch_frames_over_300_frames(model, exported):
    m = model.model
    motion = motion_for("dance:12", m.avatar(), model.fps, 300, seed=5)
    want = m.animate(motion, stages=DETAIL_ONLY)
    got = rollout_onnx(OnnxRuntime(exported, threads=1), motion)
    assert got.shape == want.vertices.shape == (300, model.template.num_vertices, 3)
    gap = np.linalg.norm(got - want.vertices, axis=-1)  # (T, V) m
    assert gap.max() < 1e-4, f"frame {int(gap.max(1).argmax())}: {gap.max():.2e} m"
    # the detail stage is in the graph: the garment is not the decoders' alone
    assert np.linalg.norm(got - want.decoded, axis=-1).max() > 1e-3


@needs_ort
def test_a_batch_of_characters_steps_as_each_alone(model, exported):
    runtime = OnnxRuntime(exported)
    avatar = model.model.avatar()
    motions = [motion_for(s, avatar, model.fps, 6) for s in ("spin", "kick", "sway")]
    rot = np.stack([mo.rotations for mo in motions])  # (3, T, J, 3, 3)
    root = np.stack([mo.root_translation for mo in motions])  # (3, T, 3)
    state, alone = runtime.initial_state(3), [runtime.initial_state(1) for _ in motions]
    for t in range(6):
        batch, state = runtime.step(rot[:, t], root[:, t], state, start=t == 0)
        for i in range(3):
            one, alone[i] = runtime.step(
                rot[i : i + 1, t], root[i : i + 1, t], alone[i], start=t == 0
            )
            np.testing.assert_allclose(batch[i], one[0], atol=1e-5)
    # a character restarted alone (start for it only) leaves the others as they were
    restart = np.array([False, True, False])
    again, _ = runtime.step(rot[:, 0], root[:, 0], state, start=restart)
    first, _ = runtime.step(rot[1:2, 0], root[1:2, 0], runtime.initial_state(1), start=True)
    np.testing.assert_allclose(again[1], first[0], atol=1e-5)
    assert np.abs(again[0] - first[0]).max() > 1e-3


@needs_ort
def test_the_json_says_what_the_inputs_mean(model, exported):
    meta = json.loads(exported.with_suffix(".json").read_text())
    m = model.model
    J, V, G = len(m.joint_names), m.template.num_vertices, m.encoder.config.gru
    assert meta["format"] == "loosefit-onnx-step/1" and meta["onnx"] == "salsa.onnx"
    from loosefit.garment.obj import read_obj

    mesh = read_obj(exported.with_suffix(".obj"))  # the garment's mesh, the graph's vertices
    assert meta["mesh"] == "salsa.obj"
    np.testing.assert_allclose(mesh.vertices, m.template.vertices, atol=1e-6)
    np.testing.assert_array_equal(mesh.faces, m.template.faces)
    assert meta["joint_names"] == list(m.joint_names) and meta["joint_names"][0] == "Hips"
    assert meta["frame_rate"] == 30.0 and meta["vertex_count"] == V == 2352
    assert meta["face_count"] == len(m.template.faces)
    assert meta["floor_height"] == pytest.approx(m.floor_height)
    assert meta["inputs"]["joint_rotations"]["shape"] == ["B", J, 3, 3]
    assert meta["inputs"]["hidden"]["shape"] == ["B", G]
    assert meta["state"] == STATE
    features = meta["motion_features"]
    assert sum(part["size"] for part in features["layout"]) == features["size"] == 191
    assert features["layout"][0]["joints"] == list(m.joint_names[1:])
    assert meta["start_of_motion"]["warm_frames"] == m.rollout_config.warm_frames
    assert "detail generator" in meta["stages"]["in_graph"]
    assert any("collision" in s for s in meta["stages"]["not_in_graph"])
    assert meta["check"]["max_difference_m"] < 1e-4
    # the graph's own names and shapes are the JSON's, and it carries the JSON too
    import onnxruntime as ort

    session = ort.InferenceSession(str(exported), providers=["CPUExecutionProvider"])
    for got, names, table in (
        (session.get_inputs(), INPUTS, meta["inputs"]),
        (session.get_outputs(), OUTPUTS, meta["outputs"]),
    ):
        assert [x.name for x in got] == list(names) == list(table)
        for x in got:
            assert x.shape[1:] == table[x.name]["shape"][1:], x.name
    embedded = json.loads(session.get_modelmeta().custom_metadata_map["loosefit"])
    assert embedded["joint_names"] == meta["joint_names"]


def test_unsupported_stages_are_named(model, tmp_path, monkeypatch):
    m = model.model
    baseline = tiny_baseline(m, "santesteban", tmp_path / "baseline.pt")
    with pytest.raises(LoosefitInputError, match=r"baseline\.pt.*'santesteban' baseline"):
        export_onnx(baseline, tmp_path / "b.onnx")
    odd = loosefit.load().model
    odd.detail = torch.nn.Linear(3, 3)
    with pytest.raises(LoosefitInputError, match=r"stage: detail.*DetailGenerator.*Linear"):
        check_exportable(odd)
    with pytest.raises(LoosefitInputError, match=r"\.onnx"):
        export_onnx(m, tmp_path / "model.txt")
    monkeypatch.setitem(sys.modules, "onnx", None)  # the extra not installed
    with pytest.raises(LoosefitInputError, match=r"loosefit\[onnx\]"):
        export_onnx(m, tmp_path / "m.onnx")
    assert not list(tmp_path.iterdir())  # nothing written


@needs_ort
@pytest.mark.parametrize(
    ("decoder", "previous_state"),
    [("decomposed", False), ("vertex", True), ("ssdr", True), ("basis", True)],
)
def test_every_decoder_exports(skirt, avatar, tmp_path, decoder, previous_state):
    tiny = tiny_model(skirt, avatar, decoder, previous_state)
    path = tmp_path / "tiny.onnx"
    export_onnx(tiny, path, OnnxExportConfig(check=True))
    motion = motion_for("spin", avatar, 30.0, 30)
    want = tiny.animate(motion, stages=MOTION_ONLY).vertices
    np.testing.assert_allclose(rollout_onnx(OnnxRuntime(path), motion), want, atol=1e-5)


@needs_ort
def test_cli_export_model_end_to_end(tmp_path, capsys):
    from loosefit.cli import main

    out = tmp_path / "engine" / "salsa.onnx"
    out.parent.mkdir()
    assert main(["export-model", str(out), "--no-detail"]) == 0
    err = capsys.readouterr().err
    assert "wrote" in err
    meta = json.loads(out.with_suffix(".json").read_text())
    # the check against PyTorch said, with the figures the JSON records
    check = meta["check"]
    said = f"equals PyTorch within {check['max_difference_m']:.2g} m over {check['frames']} frames"
    assert said in err and check["max_difference_m"] < 1e-4, err
    assert "detail generator" not in meta["stages"]["in_graph"]
    default = loosefit.load().model  # what export-model exports without a checkpoint
    motion = motion_for("kick", default.avatar(), default.fps, 20)
    want = default.animate(motion, stages=MOTION_ONLY).vertices
    got = rollout_onnx(OnnxRuntime(out), motion)
    assert np.linalg.norm(got - want, axis=-1).max() < 1e-4
    assert main(["export-model", str(tmp_path / "salsa.pt")]) == 2
    assert "expected a path ending in .onnx" in capsys.readouterr().err
    assert main(["export-model", str(tmp_path / "none" / "x.onnx")]) == 2
    assert "writable folder" in capsys.readouterr().err


@needs_ort
def test_the_runtime_refuses_other_motions_and_files(model, exported, tmp_path, avatar):
    runtime = OnnxRuntime(exported)
    fast = avatar.rest_motion(4, fps=60.0)
    with pytest.raises(LoosefitInputError, match="fps"):
        rollout_onnx(runtime, fast)
    lonely = tmp_path / "lonely.onnx"
    lonely.write_bytes(exported.read_bytes())
    with pytest.raises(LoosefitInputError, match=r"lonely\.json.*no such file"):
        OnnxRuntime(lonely)


def test_the_reference_loop_needs_no_torch():
    import subprocess

    code = "import sys, loosefit.inference.onnx.runtime; print('torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
