"""The one table of checkpoint formats and the one loader over it
(:mod:`loosefit.inference.loader`, what ``loosefit.load`` wraps): every kind of file the
project writes opens and animates; anything else is refused, naming the file, the format
found and the formats accepted."""

from __future__ import annotations

import numpy as np
import pytest

from tests.conftest import REPO

PAIR = REPO / "checkpoints" / "dance"


def test_the_table_has_one_row_per_format_and_names_what_opens_it():
    from loosefit.inference.checkpoints import FORMATS
    from loosefit.inference.engine.model import ENGINE_FORMAT
    from loosefit.inference.loader import CHECKPOINTS

    assert [row.format for row in CHECKPOINTS] == list(FORMATS)
    assert ENGINE_FORMAT in FORMATS
    assert all(row.what and row.files and callable(row.load) for row in CHECKPOINTS)


def _animates(animator, kind: str, frames: int = 4):
    """``animator`` holds a ``kind`` (a class name) and animates a few frames of a procedural
    motion."""
    from loosefit.api import motion_for

    assert type(animator.model).__name__ == kind
    motion = motion_for("sway", animator.model.avatar(), animator.fps, frames)
    result = animator.animate(motion)
    V = animator.template.num_vertices
    assert result.vertices.shape == (frames, V, 3) and np.isfinite(result.vertices).all()
    return result


@pytest.mark.parametrize(
    ("where", "kind"),
    [
        ("dance/motion.pt", "AnimationModel"),
        ("dance/generative.pt", "AnimationModel"),  # with the motion.pt beside it
        ("dance/engine.pt", "EngineModel"),
        ("dance", "AnimationModel"),  # a set's folder
        ("salsa", "AnimationModel"),  # a packaged set, its detail stage beside
        ("salsa/detail.pt", "AnimationModel"),  # a detail stage, with the motion it records
    ],
)
def test_load_opens_every_committed_file_and_it_animates(where, kind):
    import loosefit

    animator = loosefit.load(REPO / "checkpoints" / where)
    _animates(animator, kind)
    if where.startswith("salsa"):
        assert animator.model.detail is not None


def test_the_engine_tier_animates_as_its_rollout():
    import loosefit
    from loosefit.inference.engine.model import load_engine, rollout_engine

    result = loosefit.load(PAIR / "engine.pt").animate("sway", frames=10)
    want = rollout_engine(load_engine(PAIR / "engine.pt"), result.motion)
    # the same rollout; float32 sums may round apart by an ulp with other thread counts
    np.testing.assert_allclose(result.vertices, want, rtol=0, atol=1e-6)
    assert result.source == f"loosefit model {PAIR / 'engine.pt'}"


def test_the_engine_tier_refuses_what_it_cannot_run():
    import loosefit
    from loosefit.errors import LoosefitInputError

    animator = loosefit.load(PAIR / "engine.pt")
    with pytest.raises(LoosefitInputError, match="runtime"):
        animator.animate("sway", frames=3, runtime="onnx")


def test_anything_else_is_refused_naming_the_file_the_format_and_the_accepted(tmp_path):
    import torch

    import loosefit
    from loosefit.errors import LoosefitInputError

    other = tmp_path / "other.pt"
    torch.save({"format": "loosefit.sequence/1", "model": {}}, other)
    with pytest.raises(LoosefitInputError) as err:
        loosefit.load(other)
    text = str(err.value)
    assert str(other) in text and "'loosefit.sequence/1'" in text
    for fmt in ("loosefit.motion/1", "loosefit.engine/1", "loosefit.baseline/1"):
        assert repr(fmt) in text
    newer = tmp_path / "newer.pt"
    torch.save({"format": "loosefit.motion/9", "loosefit_version": "9.0"}, newer)
    with pytest.raises(LoosefitInputError, match="upgrade loosefit"):
        loosefit.load(newer)
    text_file = tmp_path / "notes.pt"
    text_file.write_text("not a checkpoint")
    with pytest.raises(LoosefitInputError, match="loosefit.load opens"):
        loosefit.load(text_file)
    with pytest.raises(LoosefitInputError, match="neither in it"):
        loosefit.load(tmp_path)
    with pytest.raises(LoosefitInputError, match="no such file"):
        loosefit.load(tmp_path / "missing.pt")


def test_a_generative_stage_alone_is_refused_with_what_would_animate(tmp_path):
    import shutil

    import loosefit
    from loosefit.errors import LoosefitInputError

    shutil.copy(PAIR / "generative.pt", tmp_path / "generative.pt")
    with pytest.raises(LoosefitInputError, match="pass the motion stage trained on it"):
        loosefit.load(tmp_path / "generative.pt")


# -- a training run's checkpoints (tiny runs on the toy data) ---------------------------------


@pytest.fixture(scope="module")
def runs(toy_dataset, skirt, tmp_path_factory):
    """Tiny motion, baseline and engine runs on the toy data (a few epochs each)."""
    import torch

    from loosefit.cli import main
    from loosefit.inference.timeline import RolloutConfig
    from loosefit.model.baselines import BaselineConfig
    from loosefit.model.generative import GenerativeConfig
    from loosefit.model.motion_encoder import MotionEncoderConfig
    from loosefit.train import baseline as tb
    from loosefit.train import generative as tg
    from loosefit.train import motion as tm

    root = tmp_path_factory.mktemp("runs")
    quiet = {"log": lambda *_: None, "progress": False}
    small = dict(uv_size=32, channels=(4, 8, 8, 8), rec_hidden=(16, 16, 16))
    gcfg = tg.TrainGenerativeConfig(
        model=GenerativeConfig(**small), epochs=2, batch_size=8, eval_every=1000
    )
    tg.train_generative(toy_dataset, root / "generative", gcfg, **quiet)
    mcfg = tm.TrainMotionConfig(
        model=MotionEncoderConfig(motion_fc=16, gru=24),
        rollout=RolloutConfig(warm_frames=2, blend_seconds=0.1),
        epochs=2,
        batch_size=2,
        window=6,
        eval_every=1000,
    )
    rest = torch.from_numpy(skirt.vertices)
    gpath = root / "generative" / "checkpoint.pt"
    tm.train_motion(toy_dataset, gpath, root / "motion", mcfg, rest_state=rest, **quiet)
    bcfg = tb.TrainBaselineConfig(
        model=BaselineConfig(method="santesteban", motion_fc=16, gru=24, head_hidden=32),
        epochs=2,
        batch_size=2,
        window=8,
        eval_every=1000,
    )
    tb.train_baseline(toy_dataset, root / "baseline", bcfg, **quiet)
    engine = ["train", "engine", "--data", str(toy_dataset), "--preset", "cpu", "--epochs", "1"]
    engine += ["--max-frames", "8", "--motion", str(root / "motion" / "model.pt")]
    assert main([*engine, "--basis", "4", "--out", str(root / "engine")]) == 0
    return root


@pytest.mark.parametrize(
    ("where", "kind"),
    [
        ("motion/model.pt", "AnimationModel"),
        ("motion/checkpoint.pt", "AnimationModel"),
        ("baseline/model.pt", "BaselineModel"),
        ("baseline/checkpoint.pt", "BaselineModel"),
        ("engine/engine.pt", "EngineModel"),
        ("engine/checkpoint.pt", "EngineModel"),
    ],
)
def test_load_opens_a_training_run_s_checkpoints_and_they_animate(runs, where, kind):
    import loosefit

    _animates(loosefit.load(runs / where), kind)


def test_a_generative_run_alone_is_refused(runs):
    import loosefit
    from loosefit.errors import LoosefitInputError

    with pytest.raises(LoosefitInputError, match="does not animate"):
        loosefit.load(runs / "generative" / "checkpoint.pt")
