"""Training on a GPU follows training on the CPU: every tensor of a step on
``config.device``, every random draw from the CPU's generator (so both devices draw the same
numbers). Run on a CUDA machine with ``pytest -m gpu tests/train/test_devices.py``."""

from __future__ import annotations

import numpy as np
import pytest
import torch

import loosefit.train.motion as tm
from loosefit.inference.timeline import RolloutConfig
from loosefit.model.generative import GenerativeConfig
from loosefit.model.motion_encoder import MotionEncoderConfig
from loosefit.train.generative import TrainGenerativeConfig, train_generative

from .conftest import SMALL

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(
        not torch.cuda.is_available(),
        reason="no CUDA device: this compares CUDA training with CPU training "
        "(run it on a GPU machine with -m gpu)",
    ),
]


DEVICES = ("cpu", "cuda")


@pytest.fixture
def ieee():
    """Convolutions and cuDNN's GRU in full float32 on the GPU (cuDNN's default is TF32,
    10-bit mantissas); matrix products are float32 by default."""
    cudnn = torch.backends.cudnn
    before = cudnn.conv.fp32_precision, cudnn.rnn.fp32_precision
    cudnn.conv.fp32_precision = cudnn.rnn.fp32_precision = "ieee"
    yield
    cudnn.conv.fp32_precision, cudnn.rnn.fp32_precision = before


def _history(run) -> list[dict]:
    return torch.load(run / "checkpoint.pt", weights_only=False, map_location="cpu")["history"]


def _same_curve(tmp_path, stage: str, rtol: float = 1e-3) -> None:
    """The runs ``stage-0`` (CPU) and ``stage-1`` (CUDA) have the same loss history."""
    cpu, cuda = (_history(tmp_path / f"{stage}-{i}") for i in range(2))
    assert len(cpu) == len(cuda) == 2
    for a, b in zip(cpu, cuda, strict=True):
        assert set(a) == set(b)
        for k in a:
            np.testing.assert_allclose(b[k], a[k], rtol=rtol, atol=1e-6, err_msg=k)


def test_cuda_trains_the_generative_and_motion_stages_as_the_cpu(
    toy_dataset, generative, skirt, tmp_path, ieee
):
    for i, device in enumerate(DEVICES):
        cfg = TrainGenerativeConfig(
            model=GenerativeConfig(**SMALL),
            epochs=2,
            batch_size=8,
            lr=2e-3,
            eval_every=1000,
            checkpoint_every=1000,
            device=device,
        )
        train_generative(
            toy_dataset, tmp_path / f"gen-{i}", cfg, log=lambda *_: None, progress=False
        )
    _same_curve(tmp_path, "gen")

    rest = torch.from_numpy(skirt.vertices)
    for i, device in enumerate(DEVICES):
        # scheduled sampling and noise on the previous states: the draws must agree
        cfg = tm.TrainMotionConfig(
            model=MotionEncoderConfig(motion_fc=16, gru=24),
            rollout=RolloutConfig(warm_frames=2, blend_seconds=0.1),
            epochs=2,
            batch_size=2,
            window=6,
            lr=3e-3,
            mirror=True,
            previous_noise=0.01,
            teacher_start=0.8,
            teacher_end=0.3,
            checkpoint_every=1000,
            eval_every=1000,
            device=device,
        )
        report = tm.train_motion(
            toy_dataset,
            generative,
            tmp_path / f"motion-{i}",
            cfg,
            log=lambda *_: None,
            progress=False,
            rest_state=rest,
        )
        assert device in report["machine"]
    _same_curve(tmp_path, "motion")


def test_cuda_trains_the_baseline_and_detail_stages_as_the_cpu(
    toy_dataset, generative, skirt, tmp_path, ieee
):
    from loosefit.model.baselines import BaselineConfig
    from loosefit.model.detail import DetailConfig
    from loosefit.train.baseline import TrainBaselineConfig, train_baseline
    from loosefit.train.detail import TrainDetailConfig, train_detail

    for i, device in enumerate(DEVICES):
        cfg = TrainBaselineConfig(
            model=BaselineConfig(method="santesteban", motion_fc=16, gru=24, head_hidden=32),
            rollout=RolloutConfig(warm_frames=2, blend_seconds=0.1),
            epochs=2,
            batch_size=2,
            window=6,
            lr=3e-3,
            checkpoint_every=1000,
            eval_every=1000,
            device=device,
        )
        train_baseline(
            toy_dataset, tmp_path / f"base-{i}", cfg, log=lambda *_: None, progress=False
        )
    _same_curve(tmp_path, "base")

    motion = tmp_path / "motion"
    cfg = tm.TrainMotionConfig(
        model=MotionEncoderConfig(motion_fc=16, gru=24),
        rollout=RolloutConfig(warm_frames=2, blend_seconds=0.1),
        epochs=2,
        batch_size=2,
        window=6,
        lr=3e-3,
        checkpoint_every=1000,
        eval_every=1000,
    )
    tm.train_motion(
        toy_dataset,
        generative,
        motion,
        cfg,
        log=lambda *_: None,
        progress=False,
        rest_state=torch.from_numpy(skirt.vertices),
    )
    for i, device in enumerate(DEVICES):
        cfg = TrainDetailConfig(
            model=DetailConfig(disc_channels=(4, 8, 8), patches=(32, 16)),
            epochs=2,
            batch_size=4,
            lr=3e-3,
            device=device,
        )
        train_detail(
            toy_dataset,
            motion / "model.pt",
            tmp_path / f"detail-{i}",
            cfg,
            log=lambda *_: None,
            progress=False,
        )
    _same_curve(tmp_path, "detail", rtol=1e-2)  # a generator and its discriminator: looser
