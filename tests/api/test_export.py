"""Exports through the API (loosefit.api.export): the same files as the exporters called
directly, and the engine tier found beside a checkpoint."""

from __future__ import annotations

import json

import pytest

from loosefit.api.export import engine_checkpoint, export_engine, export_onnx, export_sequence
from loosefit.errors import LoosefitInputError
from tests.conftest import REPO
from tests.inference.conftest import needs_ort, tiny_model

PAIR = REPO / "checkpoints" / "dance"


def _same_files(a: list, b: list) -> None:
    assert [p.name for p in a] == [p.name for p in b]
    for x, y in zip(a, b, strict=True):
        assert x.read_bytes() == y.read_bytes(), x.name


def test_a_sequence_exports_as_the_sequence_itself_would(toy_dataset, tmp_path):
    from loosefit.data.format import read_any_sequence
    from loosefit.export import ExportConfig

    seq = toy_dataset / "sequences" / "a.npz"
    config = ExportConfig(up_axis="Z")
    (tmp_path / "api").mkdir()
    (tmp_path / "direct").mkdir()
    got = export_sequence(seq, tmp_path / "api" / "a.pc2", body=False, config=config)
    want = read_any_sequence(seq).export(tmp_path / "direct" / "a.pc2", body=False, config=config)
    assert got and all(p.parent == tmp_path / "api" for p in got)
    _same_files(got, want)


def test_only_a_sequence_file_is_exported(tmp_path):
    other = tmp_path / "motion.bvh"
    other.write_text("HIERARCHY")
    with pytest.raises(LoosefitInputError, match="a sequence .npz"):
        export_sequence(other, tmp_path / "out.usdc")
    assert not (tmp_path / "out.usdc").exists()


def test_the_engine_tier_is_the_file_itself_or_the_one_beside(tmp_path):
    assert engine_checkpoint(PAIR / "engine.pt") == PAIR / "engine.pt"
    assert engine_checkpoint(PAIR / "motion.pt") == PAIR / "engine.pt"
    lonely = tmp_path / "motion.pt"
    lonely.write_bytes(b"")
    with pytest.raises(LoosefitInputError, match="train one: loosefit train engine"):
        engine_checkpoint(lonely)


@needs_ort
def test_the_onnx_export_writes_what_the_exporter_does(skirt, avatar, tmp_path):
    from loosefit.inference.onnx.export import OnnxExportConfig
    from loosefit.inference.onnx.export import export_onnx as direct

    tiny = tiny_model(skirt, avatar, "decomposed", False)
    config = OnnxExportConfig(opset=18, check=False)
    (tmp_path / "api").mkdir()
    done = export_onnx(tiny, tmp_path / "api" / "tiny.onnx", config=config)
    (tmp_path / "direct").mkdir()
    want = direct(tiny, tmp_path / "direct" / "tiny.onnx", config)
    _same_files(done.paths, want)
    assert done.metadata == json.loads(want[1].read_text())
    assert done.check is None and done.tolerance == config.tolerance
    assert done.checkpoint.name == "tiny.pt"  # the model's own record


@needs_ort
def test_a_set_s_residual_process_is_exported_beside_the_graph(skirt, avatar, tmp_path):
    import numpy as np
    import torch

    from loosefit.inference.onnx.export import OnnxExportConfig
    from loosefit.model.residual import ResidualConfig, ResidualProcess, residual_offsets

    tiny = tiny_model(skirt, avatar, "decomposed", False)
    V = skirt.num_vertices
    basis = torch.linalg.qr(torch.randn(3 * V, 3, dtype=torch.float64)).Q.T
    tiny.residual = ResidualProcess(
        basis.reshape(3, V, 3).float(),
        torch.tensor([0.03, 0.02, 0.01]),
        ResidualConfig(3, 0.9, 0.5),
    )
    done = export_onnx(tiny, tmp_path / "tiny.onnx", config=OnnxExportConfig(check=False))
    assert done.residual == tmp_path / "tiny.residual.npz" and done.residual in done.paths
    with np.load(done.residual) as z:
        assert float(z["correlation"]) == 0.9 and float(z["scale"]) == 0.5
        assert z["gain"].tolist() == [1.0, 0.0]  # the same spread every frame
        # the formula the file documents gives the rollout's offsets
        from loosefit.model.residual import residual_draws

        c = residual_draws(tiny.residual, 6, 2).numpy()
        mine = z["scale"] * (c * z["std"]) @ z["basis"].reshape(3, -1)
    want = residual_offsets(tiny.residual, 6, 2).numpy().reshape(6, -1)
    np.testing.assert_allclose(mine, want, atol=1e-6)
    assert not list(tmp_path.glob(".*partial*"))


@needs_ort
def test_the_onnx_export_checks_against_pytorch_when_asked(skirt, avatar, tmp_path):
    done = export_onnx(tiny_model(skirt, avatar, "vertex", True), tmp_path / "tiny.onnx")
    assert done.check["frames"] == 2 and done.check["max_difference_m"] < done.tolerance


@needs_ort
def test_the_engine_export_writes_what_the_exporter_does(tmp_path):
    from loosefit.api.export import EngineExportConfig
    from loosefit.inference.engine.export import export_engine as direct
    from loosefit.inference.engine.model import load_engine

    config = EngineExportConfig(check_frames=0)
    (tmp_path / "api").mkdir()
    done = export_engine(PAIR / "motion.pt", tmp_path / "api" / "engine.onnx", config=config)
    (tmp_path / "direct").mkdir()
    want = direct(load_engine(PAIR / "engine.pt"), tmp_path / "direct" / "engine.onnx", config)
    _same_files(done.paths, want)
    assert done.checkpoint == PAIR / "engine.pt" and done.check is None
    assert len(done.metadata["capsules"]) == len(json.loads(want[1].read_text())["capsules"])
