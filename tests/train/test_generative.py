"""The generative stage's configuration, evaluation, report, checkpoints and warm start
(its training itself: tests/train/test_loop.py and the others that train it)."""

from dataclasses import replace

import numpy as np
import pytest
import torch

from loosefit.errors import LoosefitInputError
from loosefit.model.generative import GarmentGenerativeModel, GenerativeConfig
from loosefit.train.frames import PreparedFrames
from loosefit.train.generative import (
    TrainGenerativeConfig,
    evaluate,
    format_report,
    load_checkpoint,
    warm_start,
)
from tests.conftest import WITH_DETAIL
from tests.meshes import grid

PACKAGED = WITH_DETAIL / "generative.pt"
needs_packaged = pytest.mark.skipif(
    not PACKAGED.is_file(), reason="checkpoints/salsa/generative.pt is not in the checkout"
)


class _Shifted:
    """A stand-in model whose reconstruction is its input moved ``shift`` m along x."""

    def __init__(self, shift: float):
        self.shift, self.evaluated = shift, False

    def eval(self):
        self.evaluated = True

    def reconstruct_all(self, posed, batch):
        return posed + torch.tensor([self.shift, 0.0, 0.0])


def _frames(lengths=(4, 2)) -> tuple[PreparedFrames, np.ndarray]:
    """Frames of flat 3 x 3 grids in two clips, each frame's root turned and moved."""
    v, faces = grid(3, 0.0, 1.0)
    n = sum(lengths)
    rng = np.random.default_rng(0)
    posed = torch.from_numpy(v[None] + rng.normal(0, 0.01, (n, 9, 3)).astype(np.float32))
    angle = torch.linspace(0, 1, n)
    heading = torch.zeros(n, 3, 3)
    heading[:, 0, 0], heading[:, 0, 1] = angle.cos(), -angle.sin()
    heading[:, 1, 0], heading[:, 1, 1] = angle.sin(), angle.cos()
    heading[:, 2, 2] = 1
    clip = torch.cat([torch.full((k,), i) for i, k in enumerate(lengths)])
    frame = torch.cat([torch.arange(k) for k in lengths])
    frames = PreparedFrames(
        names=[f"clip{i}" for i in range(len(lengths))],
        clip=clip,
        frame=frame,
        posed=posed,
        unposed=posed.clone(),
        heading=heading,
        origin=torch.randn(n, 3),
        fps=30.0,
    )
    return frames, faces


def test_evaluation_reports_the_known_error_per_clip_and_overall():
    frames, faces = _frames()
    model = _Shifted(0.02)  # 2 cm everywhere, in the root frame and so in the world
    out = evaluate(model, frames, faces)
    assert model.evaluated
    assert out["frames"] == 6 and sorted(out["clips"]) == ["clip0", "clip1"]
    assert out["rmse_cm"] == pytest.approx(2.0, rel=1e-4)
    for name, n in (("clip0", 4), ("clip1", 2)):
        assert out["clips"][name]["frames"] == n
        assert out["clips"][name]["rmse_cm"] == pytest.approx(2.0, rel=1e-4)
    # a flat sheet moved within its plane: every vertex still lies on the other sheet,
    # except at the border, 2 cm beyond it
    assert 0 < out["hausdorff_cm"] <= 2.0 + 1e-3
    assert out["sted"] == pytest.approx(0.0, abs=1e-6)  # a rigid shift keeps every edge
    exact = evaluate(_Shifted(0.0), frames, faces)
    assert exact["rmse_cm"] == 0.0 and exact["hausdorff_cm"] == pytest.approx(0.0, abs=1e-4)


def test_the_report_is_a_table_of_both_splits():
    split = {"frames": 10, "rmse_cm": 1.23456, "hausdorff_cm": 2.5, "sted": 0.01234}
    report = {
        "decoder": "uv",
        "epochs": 7,
        "train": split,
        "test": split | {"frames": 4},
        "parameters": 12345,
        "seconds_per_epoch": 1.5,
        "peak_memory_mb": 321.4,
        "machine": "x86_64, cpu",
    }
    text = format_report(report)
    lines = text.splitlines()
    assert lines[0] == "# Generative model (uv decoder), 7 epochs"
    assert "| train | 10 | 1.235 | 2.500 | 0.0123 |" in lines
    assert "| test | 4 | 1.235 | 2.500 | 0.0123 |" in lines
    assert "12,345 parameters; 1.50 s per epoch; peak memory 321 MB; x86_64, cpu." in lines


def test_the_configuration_refuses_an_unknown_precision():
    with pytest.raises(LoosefitInputError, match="precision"):
        TrainGenerativeConfig(precision="fp16").validate()
    TrainGenerativeConfig(precision="bf16").validate()
    cpu = TrainGenerativeConfig.PRESETS["cpu"]
    assert cpu["model"].uv_size == 64 and cpu["lr"] == 1.0e-3


@needs_packaged
def test_a_packaged_model_is_no_run_checkpoint():
    with pytest.raises(LoosefitInputError) as err:
        load_checkpoint(PACKAGED)
    assert err.value.field == "config" and err.value.found == "none (a packaged model)"


@needs_packaged
def test_a_warm_start_takes_the_weights_of_the_same_configuration_only():
    from loosefit.inference.checkpoints import load_generative, read_generative

    source, _ = load_generative(PACKAGED)
    _, template = read_generative(PACKAGED, None, "cpu")
    fresh = GarmentGenerativeModel(template, source.config)
    warm_start(fresh, PACKAGED, template, source.config)
    for key, value in source.state_dict().items():
        assert torch.equal(fresh.state_dict()[key], value), key
    other = replace(source.config, latent=source.config.latent + 1)
    with pytest.raises(LoosefitInputError) as err:
        warm_start(fresh, PACKAGED, template, other)
    assert err.value.field == "model_config"
    assert f"'latent': {source.config.latent + 1}" in err.value.expected


def test_a_generative_config_round_trips_through_its_dict():
    cfg = TrainGenerativeConfig(
        epochs=3,
        model=GenerativeConfig(uv_size=32, latent=8),
        laplacian="cotangent",
        mirror=True,
    )
    back = TrainGenerativeConfig.from_dict(cfg.to_dict())
    assert back == cfg and back.model.latent == 8 and back.mirror
