"""The detail module's training, checkpoints and wiring into rollouts (paper 3.4)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch

import loosefit
import loosefit.inference.animator as inf
import loosefit.train.detail as td
import loosefit.train.motion as tm
from loosefit.cli import main
from loosefit.data.format import DatasetReader
from loosefit.errors import LoosefitInputError
from loosefit.inference.animator import collision_records
from loosefit.inference.checkpoints import model_fingerprint
from loosefit.inference.rollout import RolloutOptions, rollout
from loosefit.inference.stages import MOTION_ONLY, Stages
from loosefit.inference.timeline import RolloutConfig
from loosefit.model.detail import DetailConfig
from loosefit.model.motion_encoder import MotionEncoderConfig

TINY = DetailConfig(disc_channels=(4, 8, 8), patches=(32, 16))  # the toy UV maps are 32 texels


@pytest.fixture(scope="module")
def motion(toy_dataset, generative, skirt, tmp_path_factory):
    """A small motion stage trained on the toy data: its model.pt."""
    out = tmp_path_factory.mktemp("motion")
    cfg = tm.TrainMotionConfig(
        model=MotionEncoderConfig(motion_fc=16, gru=24),
        rollout=RolloutConfig(warm_frames=2, blend_seconds=0.1),
        epochs=6,
        batch_size=2,
        window=6,
        lr=3e-3,
        checkpoint_every=1,
        eval_every=1000,
    )
    tm.train_motion(
        toy_dataset,
        generative,
        out,
        cfg,
        log=lambda *_: None,
        progress=False,
        rest_state=torch.from_numpy(skirt.vertices),
    )
    return out / "model.pt"


def _config(**kw) -> td.TrainDetailConfig:
    cfg = td.TrainDetailConfig(model=TINY, epochs=8, batch_size=4, lr=3e-3)
    return dataclasses.replace(cfg, **kw)


@pytest.fixture(scope="module")
def trained(toy_dataset, motion, tmp_path_factory):
    out = tmp_path_factory.mktemp("detail")
    report = td.train_detail(
        toy_dataset, motion, out, _config(), log=lambda *_: None, progress=False
    )
    return out, report


def test_adversarial_training_lowers_the_l1_loss(trained):
    out, report = trained
    history = report["history"]
    assert history[-1]["position"] < 0.95 * history[0]["position"]
    assert {"discriminator", "adversarial", "laplacian"} <= set(history[0])
    pairs = torch.load(out / "pairs.pt", weights_only=True)
    assert pairs["clips"] == ["a", "b"]  # the training clips, rolled out by the motion stage
    assert pairs["decoded"].shape == pairs["target"].shape == (32, 96, 3)
    assert np.isfinite(report["test_with"]["rmse_cm"])


def test_the_pairs_are_the_motion_stages_own_rollouts(trained, motion, toy_dataset):
    out, _ = trained
    model = inf.load_animation_model(motion)
    reader = DatasetReader(toy_dataset)
    first = reader.read("a").motion
    pairs = torch.load(out / "pairs.pt", weights_only=True)
    result = model.animate(first, stages=MOTION_ONLY)
    np.testing.assert_allclose(pairs["codes"][:16].numpy(), result.codes, atol=1e-6)


def test_without_discriminator_has_no_adversarial_terms(toy_dataset, motion, tmp_path):
    report = td.train_detail(
        toy_dataset,
        motion,
        tmp_path,
        _config(epochs=2, discriminator=False),
        log=lambda *_: None,
        progress=False,
    )
    assert "discriminator" not in report["history"][0]
    assert not report["discriminator"]
    assert "edge" not in report["history"][0]  # the paper's Eq. 13 unless asked


def test_the_edge_length_term_is_trained_when_weighted(toy_dataset, motion, tmp_path):
    cfg = _config(epochs=2, discriminator=False)
    cfg.loss.edge = 1.0
    report = td.train_detail(
        toy_dataset, motion, tmp_path, cfg, log=lambda *_: None, progress=False
    )
    assert report["history"][0]["edge"] > 0
    assert report["history"][-1]["total"] < report["history"][0]["total"]


def test_resume_continues_where_it_stopped(toy_dataset, motion, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    quiet = dict(log=lambda *_: None, progress=False)
    td.train_detail(toy_dataset, motion, a, _config(epochs=3), **quiet)
    td.train_detail(toy_dataset, motion, b, _config(epochs=3), **quiet)
    ckpt = torch.load(b / "checkpoint.pt", weights_only=False)
    # a run stopped after epoch 2 of 3: roll its checkpoint back to epoch 2 and resume
    c = tmp_path / "c"
    td.train_detail(toy_dataset, motion, c, _config(epochs=2), **quiet)
    (c / "config.json").write_text(json.dumps(json.loads((b / "config.json").read_text())))
    td.train_detail(toy_dataset, motion, c, _config(epochs=3), **quiet)
    resumed = torch.load(c / "checkpoint.pt", weights_only=False)
    assert resumed["epoch"] == ckpt["epoch"] == 3
    for k, v in ckpt["model"].items():
        torch.testing.assert_close(resumed["model"][k], v)


def test_detail_runs_in_animate_and_can_be_switched_off(trained, motion, toy_dataset):
    out, _ = trained
    model = loosefit.load(out / "model.pt").model
    assert model.detail is not None
    m = DatasetReader(toy_dataset).read("c").motion
    plain = model.animate(m, stages=MOTION_ONLY)
    detailed = model.animate(m, stages=Stages(collision=False))
    assert not np.array_equal(plain.vertices, detailed.vertices)
    np.testing.assert_array_equal(detailed.decoded, plain.vertices)
    fed = model.animate(m, stages=Stages(collision=False, feedback=True))
    assert np.isfinite(fed.vertices).all()
    np.testing.assert_allclose(fed.vertices[0], detailed.vertices[0], atol=1e-6)  # same first frame


def test_the_later_stages_beside_the_motion_stage_change_nothing(trained, toy_dataset):
    out, _ = trained
    model = loosefit.load(out / "model.pt").model
    m = DatasetReader(toy_dataset).read("c").motion
    assert m.num_frames > 6 and m.num_frames % 3

    def run(overlap: bool):  # chunks of 3 frames: several, and a remainder
        later = model.later_stages(m, Stages(), model.detail)
        options = RolloutOptions(later, overlap=overlap, chunk=3)
        return rollout(model.motion_stage(), m, options), collision_records(later)

    (apart, apart_records), (beside, beside_records) = run(False), run(True)
    np.testing.assert_array_equal(beside.vertices, apart.vertices)
    assert beside_records == apart_records and len(beside_records) == m.num_frames
    assert set(beside.stage_seconds) == {"motion", "detail", "lengths", "collision"}


def test_a_detail_stage_of_another_motion_stage_is_refused(trained, motion, tmp_path):
    out, _ = trained
    model = inf.load_animation_model(motion)
    with torch.no_grad():
        model.encoder.fc.bias.add_(0.5)  # another motion stage
    with pytest.raises(LoosefitInputError, match="fingerprint") as err:
        inf.attach_detail(model, out / "model.pt")
    data = torch.load(out / "model.pt", weights_only=False)
    assert data["fingerprints"]["motion"] in str(err.value)
    assert model_fingerprint(model.encoder) in str(err.value)


def test_package_carries_the_detail_stage(trained, motion, tmp_path, toy_dataset):
    out, _ = trained
    pack = tmp_path / "pack"
    assert (
        main(["package", str(motion), "--detail", str(out / "model.pt"), "--out", str(pack)]) == 0
    )
    assert sorted(p.name for p in pack.iterdir()) == ["detail.pt", "generative.pt", "motion.pt"]
    model = loosefit.load(pack / "motion.pt").model
    assert model.detail is not None
    m = DatasetReader(toy_dataset).read("c").motion
    a = model.animate(m, stages=Stages(collision=False)).vertices
    b = loosefit.load(out / "model.pt").model.animate(m, stages=Stages(collision=False)).vertices
    np.testing.assert_allclose(a, b, atol=5e-4)  # the packaged generative stage is half precision


def test_animate_without_later_stages_is_the_motion_stage_rollout(
    trained, motion, toy_dataset, tmp_path
):
    out, _ = trained
    seq = DatasetReader(toy_dataset).read("c")
    motion_file = tmp_path / "c.npz"
    seq.motion.save(motion_file)
    dest = tmp_path / "anim"
    args = [
        "animate",
        str(out / "model.pt"),
        str(motion_file),
        "--out",
        str(dest),
        "--no-detail",
        "--no-lengths",
        "--no-collision",
    ]
    assert main(args) == 0
    got = np.load(next(dest.glob("*.npz")))["garment_vertices"]
    model = inf.load_animation_model(motion)
    want = rollout(model.motion_stage(), seq.motion).vertices
    np.testing.assert_array_equal(got, want)


def test_warm_start_begins_from_the_given_generator(trained, toy_dataset, motion, tmp_path):
    run, _ = trained
    quiet = dict(log=lambda *_: None, progress=False)
    td.train_detail(
        toy_dataset,
        motion,
        tmp_path / "fine",
        _config(epochs=1, lr=0.0, init=str(run / "model.pt")),
        **quiet,
    )
    a = torch.load(run / "model.pt", weights_only=False)["model"]
    b = torch.load(tmp_path / "fine" / "checkpoint.pt", weights_only=False)["model"]
    assert all(torch.equal(a[k].float(), b[k].float()) for k in a)
    other = DetailConfig(disc_channels=(4, 8, 8), patches=(32, 16), global_hidden=(8, 4))
    with pytest.raises(LoosefitInputError, match="model"):
        td.train_detail(
            toy_dataset,
            motion,
            tmp_path / "other",
            _config(epochs=1, model=other, init=str(run / "model.pt")),
            **quiet,
        )
