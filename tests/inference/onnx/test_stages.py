"""``animate(..., runtime="onnx")``: the learned stages in onnxruntime give
PyTorch's garments, the stages after them are the same, and what cannot run is refused by
name."""

from __future__ import annotations

import sys

import numpy as np
import pytest
import torch

from loosefit.api import motion_for
from loosefit.errors import LoosefitInputError
from loosefit.inference.stages import MOTION_ONLY, Stages
from loosefit.sequence import GarmentSequence
from tests.inference.conftest import needs_ort, tiny_baseline, tiny_model

NO_COLLISION = Stages(collision=False)  # detail and edge lengths, overlapped on a thread


def _gap(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(T, V) distances (m) between garments (T, V, 3)."""
    return np.linalg.norm(a - b, axis=-1)


@needs_ort
def test_onnx_runtime_animates_the_torch_frames_over_300_frames(model):
    m = model.model
    motion = motion_for("dance:12", m.avatar(), model.fps, 300, seed=5)
    want = m.animate(motion, stages=NO_COLLISION)
    got = m.animate(motion, stages=NO_COLLISION, runtime="onnx")
    assert got.vertices.shape == want.vertices.shape == (300, m.template.num_vertices, 3)
    gap = _gap(got.vertices, want.vertices)
    assert gap.max() < 1e-4, f"frame {int(gap.max(1).argmax())}: {gap.max():.2e} m"
    assert _gap(got.decoded, want.decoded).max() < 1e-4
    np.testing.assert_allclose(got.codes, want.codes, atol=1e-4)
    # the detail and length stages ran on what the graphs gave
    assert _gap(got.vertices, got.decoded).max() > 1e-3
    assert (
        set(got.stage_cpu_seconds) == set(want.stage_cpu_seconds) == {"motion", "detail", "lengths"}
    )
    assert set(got.stage_seconds) == set(want.stage_seconds)


@needs_ort
def test_the_whole_pipeline_and_feedback_run_through_onnx(model):
    m = model.model
    motion = motion_for("spin", m.avatar(), model.fps, 30)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # as the one-thread benchmark: stages one after another
    try:
        one = Stages(overlap=False)
        want = m.animate(motion, stages=one)
        got = m.animate(motion, stages=one, runtime="onnx")
    finally:
        torch.set_num_threads(threads)
    assert set(got.stage_cpu_seconds) == {"motion", "detail", "lengths", "collision"}
    assert all(v > 0 for v in got.stage_cpu_seconds.values())
    assert len(got.collisions) == 30
    assert _gap(got.decoded, want.decoded).max() < 1e-4
    # collision handling is the same code; it may turn a micrometre apart at the edge of
    # its contact set into more on a few vertices (torch's own garment does as much)
    gap = _gap(got.vertices, want.vertices)
    assert np.quantile(gap, 0.999) < 1e-4, f"{np.quantile(gap, 0.999):.2e} m"
    # the garment after detail and lengths fed back as the next frame's previous state
    loop = Stages(collision=False, feedback=True)
    want = m.animate(motion, stages=loop)
    got = m.animate(motion, stages=loop, runtime="onnx")
    assert _gap(got.vertices, want.vertices).max() < 1e-4


@needs_ort
def test_an_encoder_without_the_previous_state_runs_too(skirt, avatar):
    tiny = tiny_model(skirt, avatar, "decomposed", previous_state=False)
    motion = motion_for("spin", avatar, 30.0, 20)
    want = tiny.animate(motion, stages=MOTION_ONLY).vertices
    got = tiny.animate(motion, stages=MOTION_ONLY, runtime="onnx").vertices
    np.testing.assert_allclose(got, want, atol=1e-5)


def test_onnx_runtime_refusals_are_clear(model, monkeypatch, tmp_path):
    m = model.model
    motion = motion_for("sway", m.avatar(), model.fps, 3)
    with pytest.raises(LoosefitInputError, match=r"runtime.*'torch' or 'onnx'.*'tensorrt'"):
        m.animate(motion, runtime="tensorrt")
    baseline = tiny_baseline(m, "virtual-bones", tmp_path / "baseline.pt")
    with pytest.raises(
        LoosefitInputError, match=r"baseline\.pt.*runtime.*'virtual-bones' baseline"
    ):
        baseline.animate(motion, runtime="onnx")
    monkeypatch.setattr(m, "_onnx", None)  # not built yet in this process
    monkeypatch.setitem(sys.modules, "onnxruntime", None)  # the extra not installed
    with pytest.raises(
        LoosefitInputError, match=r"runtime 'onnx'.*onnxruntime.*pip install 'loosefit\[onnx\]'"
    ):
        m.animate(motion, runtime="onnx")
    with pytest.raises(LoosefitInputError, match=r"loosefit\[onnx\]"):
        model.animate(motion, runtime="onnx")  # the API's front door says the same


@needs_ort
def test_cli_animate_runtime_onnx(model, tmp_path, capsys, monkeypatch):
    from loosefit.cli import main

    args = ["animate", "sway", "--frames", "8", "--no-collision"]
    assert main([*args, "--out", str(tmp_path / "torch.npz")]) == 0
    assert main([*args, "--runtime", "onnx", "--out", str(tmp_path / "onnx.npz")]) == 0
    want = GarmentSequence.load(tmp_path / "torch.npz").garment_vertices
    got = GarmentSequence.load(tmp_path / "onnx.npz").garment_vertices
    assert got.shape == (8, model.template.num_vertices, 3)
    assert _gap(got, want).max() < 1e-4
    with pytest.raises(SystemExit):  # argparse: not one of the choices
        main([*args, "--runtime", "tensorrt", "--out", str(tmp_path / "x.npz")])
    assert "invalid choice: 'tensorrt'" in capsys.readouterr().err
    monkeypatch.setitem(sys.modules, "onnxruntime", None)  # the extra not installed
    assert main([*args, "--runtime", "onnx", "--out", str(tmp_path / "y.npz")]) == 2
    assert "pip install 'loosefit[onnx]'" in capsys.readouterr().err
    assert not (tmp_path / "y.npz").exists()


@needs_ort
def test_a_batch_through_onnx_gives_each_motion_its_torch_garment(model):
    """``animate_batch(..., runtime="onnx")``: one onnxruntime call per frame for all the
    characters, the garments PyTorch's batch gives; with ``collision="realtime"`` each
    motion's garment is the one its own realtime ``animate`` gives."""
    m = model.model
    motions = [
        motion_for(spec, m.avatar(), model.fps, n, seed=3)
        for spec, n in (("dance:4", 40), ("spin", 28))
    ]
    want = m.animate_batch(motions, stages=MOTION_ONLY)
    got = m.animate_batch(motions, stages=MOTION_ONLY, runtime="onnx")
    for w, g, motion in zip(want, got, motions, strict=True):
        assert g.vertices.shape == (motion.num_frames, m.template.num_vertices, 3)
        assert _gap(g.vertices, w.vertices).max() < 1e-4
        np.testing.assert_allclose(g.codes, w.codes, atol=1e-4)
    quick = m.animate_batch(motions, runtime="onnx", collision="realtime")
    for q, motion in zip(quick, motions, strict=True):
        alone = m.animate(motion, runtime="onnx", collision="realtime")
        assert len(q.collisions) == motion.num_frames
        # as test_batch_inference: rounding can move a few vertices by under 2 mm
        off = _gap(q.vertices, alone.vertices)
        assert (off > 2e-4).mean() < 1e-3 and off.max() < 2e-3
    with pytest.raises(LoosefitInputError, match="runtime"):
        m.animate_batch(motions, runtime="tensorrt")
