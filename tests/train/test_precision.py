"""Mixed precision (``precision="bf16"``) of the generative and motion stages on the CPU: the
networks' forward passes under bf16 autocast, everything the loss and the optimiser see in
float32."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

import loosefit.train.motion as tm
import loosefit.train.motion_window as mw
from loosefit.data.format import DatasetReader
from loosefit.errors import LoosefitInputError
from loosefit.geometry.laplacian import Laplacian
from loosefit.inference.animator import load_animation_model
from loosefit.inference.timeline import RolloutConfig
from loosefit.model.generative import GenerativeConfig
from loosefit.model.motion_encoder import MotionEncoderConfig
from loosefit.train.clips import prepare_clips, stack_clips
from loosefit.train.generative import TrainGenerativeConfig, _float32, train_generative

from .conftest import SMALL


@pytest.fixture
def one_thread():
    """Tiny networks: one thread is as fast, and far faster on a shared, busy CPU."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def _generative_config(**kw) -> TrainGenerativeConfig:
    return TrainGenerativeConfig(
        model=GenerativeConfig(**SMALL),
        epochs=3,
        batch_size=8,
        lr=2e-3,
        eval_every=1000,
        checkpoint_every=1000,
        **kw,
    )


def _motion_config(**kw) -> tm.TrainMotionConfig:
    return tm.TrainMotionConfig(
        model=MotionEncoderConfig(motion_fc=16, gru=24),
        rollout=RolloutConfig(warm_frames=2, blend_seconds=0.1),
        epochs=3,
        batch_size=2,
        window=6,
        lr=3e-3,
        previous="teacher",
        checkpoint_every=1000,
        eval_every=1000,
        **kw,
    )


def _history(run) -> list[dict]:
    return torch.load(run / "checkpoint.pt", weights_only=False)["history"]


def _close(fp32: list[dict], bf16: list[dict]) -> None:
    """bf16's loss history: finite, its first epoch (the first 4 steps) within 3% of fp32's,
    and falling as fp32's does. (Later epochs drift apart by up to ~10% on these tiny runs:
    Adam turns rounding-sized gradient differences into whole steps, the loss falling fast.)"""
    assert len(fp32) == len(bf16) == 3
    assert all(np.isfinite(v) for h in bf16 for v in h.values())
    np.testing.assert_allclose(bf16[0]["total"], fp32[0]["total"], rtol=0.03)
    assert bf16[-1]["total"] < 0.7 * bf16[0]["total"] and fp32[-1]["total"] < 0.7 * fp32[0]["total"]


def test_precision_is_fp32_or_bf16(toy_dataset, tmp_path):
    assert _generative_config().precision == _motion_config().precision == "fp32"
    for make in (_generative_config, _motion_config):
        with pytest.raises(LoosefitInputError, match="precision"):
            make(precision="fp16")
    with pytest.raises(LoosefitInputError, match="precision"):
        TrainGenerativeConfig.preset("cpu", precision="half")
    from loosefit.cli import main

    detail = [
        "train",
        "detail",
        "--data",
        str(toy_dataset),
        "--motion",
        "x.pt",
        "--precision",
        "bf16",
        "--out",
        str(tmp_path / "d"),
    ]
    with pytest.raises(SystemExit) as exit_:  # fp32 only there: not a flag of the stage
        main(detail)
    assert exit_.value.code == 2 and not (tmp_path / "d").exists()


def test_bf16_generative_training_follows_fp32(toy_dataset, tmp_path, one_thread):
    runs = {}
    for precision in ("fp32", "bf16"):
        runs[precision] = tmp_path / precision
        train_generative(
            toy_dataset,
            runs[precision],
            _generative_config(precision=precision),
            log=lambda *_: None,
            progress=False,
        )
    _close(_history(runs["fp32"]), _history(runs["bf16"]))
    weights = torch.load(runs["bf16"] / "checkpoint.pt", weights_only=False)["model"]
    for k, w in weights.items():
        assert w.dtype != torch.bfloat16 and torch.isfinite(w.float()).all(), k  # float32 kept


def test_bf16_forward_gives_float32_outputs(generative):
    from loosefit.inference.checkpoints import load_generative
    from loosefit.train.common import autocast

    model, _ = load_generative(generative)
    x = model.decode_all(torch.randn(4, model.config.latent) * 0.1)  # (4, V, 3) garments
    with autocast("bf16", torch.device("cpu")):
        out = model(x, sample=False)
    assert out.mu.dtype == torch.bfloat16  # the encoder did run in bf16
    out = _float32(out)
    for name in ("vertices", "mu", "logvar", "z", "unposed", "offsets"):
        assert getattr(out, name).dtype == torch.float32, name
    exact = model(x, sample=False).vertices
    assert (out.vertices - exact).abs().max() < 0.01  # m: bf16's three digits, not garbage


def test_bf16_motion_training_follows_fp32(toy_dataset, generative, skirt, tmp_path, one_thread):
    rest = torch.from_numpy(skirt.vertices)
    runs = {}
    for precision in ("fp32", "bf16"):
        runs[precision] = tmp_path / precision
        tm.train_motion(
            toy_dataset,
            generative,
            runs[precision],
            _motion_config(precision=precision),
            log=lambda *_: None,
            progress=False,
            rest_state=rest,
        )
    _close(_history(runs["fp32"]), _history(runs["bf16"]))
    model = load_animation_model(runs["bf16"] / "model.pt")
    assert all(torch.isfinite(p).all() for p in model.encoder.parameters())

    # one window of the same weights: float32 state carried on, terms close to fp32's
    clips = prepare_clips(
        DatasetReader(toy_dataset),
        "train",
        model.generative,
        model.floor_height,
        model.rollout_config,
    )
    batch = stack_clips(clips)
    lap = Laplacian(skirt.faces, skirt.num_vertices)
    terms = {}
    for precision in ("fp32", "bf16"):
        hidden = model.encoder.initial_hidden(2)
        prev = model.rest_state[None].expand(2, -1, -1)
        window = mw.run_window(
            model.encoder,
            model.generative,
            lap,
            batch,
            0,
            12,
            hidden=hidden,
            previous=prev,
            teacher=0.0,
            loss=mw.MotionLossConfig(),
            precision=precision,
        )
        terms[precision], hidden, prev = window.terms, window.hidden, window.previous
        assert hidden.dtype == prev.dtype == terms[precision]["total"].dtype == torch.float32
    for k, v in terms["fp32"].items():  # (measured: total 0.5%, the Laplacian term 2% apart)
        np.testing.assert_allclose(
            float(terms["bf16"][k].detach()),
            float(v.detach()),
            rtol=0.02 if k == "total" else 0.05,
            err_msg=k,
        )


def test_runs_from_before_the_precision_field_resume_as_fp32(tmp_path):
    import json

    from loosefit.train.loop import open_run

    cfg = _motion_config()
    assert tm.TrainMotionConfig.from_dict(cfg.to_dict()) == cfg
    stored = {"dataset": "d", "train": cfg.to_dict()}
    old = json.loads(json.dumps(stored))
    del old["train"]["precision"]  # a run recorded before the field
    assert tm.TrainMotionConfig.from_dict(old["train"]).precision == "fp32"
    run = tmp_path / "run"
    run.mkdir()
    (run / "config.json").write_text(json.dumps(old))
    open_run(run, stored)  # the same run: it resumes
    bf16 = {"dataset": "d", "train": dataclasses.replace(cfg, precision="bf16").to_dict()}
    with pytest.raises(LoosefitInputError, match="another run"):
        open_run(run, bf16)
    other = {"dataset": "d", "train": {"epochs": 3}}  # a stage without the field
    open_run(tmp_path / "other", other)
    open_run(tmp_path / "other", other)
