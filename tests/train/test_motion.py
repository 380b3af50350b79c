"""The dynamic motion encoder's training, checkpoints, rollouts and their errors (paper 3.3)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import torch

import loosefit.inference.animator as inf
import loosefit.train.loop as loop
import loosefit.train.motion as tm
import loosefit.train.motion_window as mw
from loosefit.data.format import DatasetReader
from loosefit.errors import LoosefitInputError
from loosefit.eval.rollouts import evaluate_rollouts
from loosefit.inference.package import package_model
from loosefit.inference.timeline import RolloutConfig
from loosefit.model.motion_encoder import MotionEncoderConfig
from loosefit.model.motion_features import feature_joints, num_features
from loosefit.motion.motions import load_motion
from loosefit.sequence import GarmentSequence
from loosefit.train.clips import prepare_clips
from loosefit.types import Motion


def _config(**kw) -> tm.TrainMotionConfig:
    cfg = tm.TrainMotionConfig(
        model=MotionEncoderConfig(motion_fc=16, gru=24),
        rollout=RolloutConfig(warm_frames=2, blend_seconds=0.1),
        epochs=12,
        batch_size=2,
        window=6,
        lr=3e-3,
        checkpoint_every=1,
        eval_every=1000,
    )
    return dataclasses.replace(cfg, **kw)


def _train(toy_dataset, generative, skirt, out, **kw):
    return tm.train_motion(
        toy_dataset,
        generative,
        out,
        _config(**kw),
        log=lambda *_: None,
        progress=False,
        rest_state=torch.from_numpy(skirt.vertices),
    )


@pytest.fixture(scope="module")
def trained(toy_dataset, generative, skirt, tmp_path_factory):
    out = tmp_path_factory.mktemp("motion")
    report = _train(toy_dataset, generative, skirt, out)
    return out, report


def test_training_lowers_the_loss_and_reports_rollouts(trained):
    out, report = trained
    history = torch.load(out / "checkpoint.pt", weights_only=False)["history"]
    assert history[-1]["total"] < 0.7 * history[0]["total"]
    assert history[0]["teacher"] == 1.0 and history[-1]["teacher"] == 0.0  # scheduled sampling
    test = report["test"]
    assert list(test["clips"]) == ["c"] and test["clips"]["c"]["frames"] == 16
    assert len(test["clips"]["c"]["rmse_per_frame_cm"]) == 16
    assert test["horizons"] == {}  # 16 frames: shorter than every horizon
    assert np.isfinite(test["rmse_cm"]) and test["hausdorff_cm"] > 0
    assert (out / "model.pt").is_file() and (out / "report.md").is_file()


def test_rollout_is_deterministic_and_on_the_motion(trained, toy_dataset):
    out, _ = trained
    model = inf.load_animation_model(out / "model.pt")
    motion = DatasetReader(toy_dataset).read("c").motion
    a, b = model.animate(motion), model.animate(motion)
    assert a.vertices.shape == (16, model.template.num_vertices, 3)
    np.testing.assert_array_equal(a.vertices, b.vertices)
    # The garment goes where the body goes: near the root in every frame.
    gap = np.linalg.norm(a.vertices.mean(1) - motion.root_translation, axis=-1)
    assert gap.max() < 0.6
    assert a.frames == 16 + 2 + 3 and a.frames_per_second > 0


def test_resume_after_a_kill_gives_the_same_model(
    toy_dataset, generative, skirt, tmp_path, monkeypatch, trained
):
    saves = []
    real = loop.save_checkpoint

    def dying(path, *a, **kw):
        real(path, *a, **kw)
        saves.append(path)
        if len(saves) == 5:
            raise KeyboardInterrupt  # killed right after the 5th epoch's checkpoint

    monkeypatch.setattr(loop, "save_checkpoint", dying)
    with pytest.raises(KeyboardInterrupt):
        _train(toy_dataset, generative, skirt, tmp_path / "run")
    monkeypatch.setattr(loop, "save_checkpoint", real)
    assert not (tmp_path / "run" / "report.json").exists()  # nothing that looks finished
    lines = []
    tm.train_motion(
        toy_dataset,
        generative,
        tmp_path / "run",
        _config(),
        log=lines.append,
        progress=False,
        rest_state=torch.from_numpy(skirt.vertices),
    )
    assert any("resumed" in s and "epoch 5" in s for s in lines)
    whole = torch.load(trained[0] / "model.pt", weights_only=False)["model"]
    resumed = torch.load(tmp_path / "run" / "model.pt", weights_only=False)["model"]
    for k in whole:
        torch.testing.assert_close(resumed[k], whole[k])


def test_ablation_without_previous_state_trains(toy_dataset, generative, skirt, tmp_path):
    report = _train(
        toy_dataset,
        generative,
        skirt,
        tmp_path / "nops",
        epochs=3,
        model=MotionEncoderConfig(motion_fc=16, gru=24, previous_state=False),
    )
    assert report["previous_state"] is False and np.isfinite(report["test"]["rmse_cm"])
    model = inf.load_animation_model(tmp_path / "nops" / "model.pt")
    assert not hasattr(model.encoder, "state_encoder")


def test_encoder_on_the_lower_body_joints(toy_dataset, generative, skirt, tmp_path, avatar):
    report = _train(
        toy_dataset,
        generative,
        skirt,
        tmp_path / "lower",
        epochs=2,
        model=MotionEncoderConfig(motion_fc=16, gru=24, joints="lower"),
    )
    assert np.isfinite(report["test"]["rmse_cm"])
    model = inf.load_animation_model(tmp_path / "lower" / "model.pt")
    assert model.encoder.config.joints == "lower"
    lower = feature_joints(model.joint_names, "lower")
    assert (
        model.encoder.num_features
        == num_features(len(lower) + 1)
        < num_features(len(model.joint_names))
    )
    assert tm.TrainMotionConfig.preset("cpu", joints="lower").model.joints == "lower"
    motion = load_motion("walk", avatar).slice(0, 12)
    a = model.animate(motion).vertices
    # an arm waved differently changes nothing the encoder sees
    waved = motion.rotations.copy()
    waved[:, list(motion.joint_names).index("RightArm")] = np.array(
        [[0, -1, 0], [1, 0, 0], [0, 0, 1]], np.float32
    )
    b = model.animate(dataclasses.replace(motion, rotations=waved)).vertices
    np.testing.assert_array_equal(a, b)


def test_bad_inputs_are_clear_errors(trained, toy_dataset, generative, avatar, tmp_path):
    out, _ = trained
    model = inf.load_animation_model(out / "model.pt")
    motion = DatasetReader(toy_dataset).read("c").motion
    fewer = Motion(
        motion.joint_names[:-1],
        motion.rotations[:, :-1],
        motion.root_translation,
        motion.fps,
        "fewer",
    )
    with pytest.raises(LoosefitInputError, match="joint_names"):
        model.animate(fewer)
    # A generative checkpoint where the motion stage's is expected.
    with pytest.raises(LoosefitInputError, match="generative stage"):
        inf.load_animation_model(generative)
    # Another generative model than the encoder was trained on.
    other = torch.load(generative, weights_only=False)
    other["model"] = {
        k: v + 0.01 if v.is_floating_point() else v for k, v in other["model"].items()
    }
    torch.save(other, tmp_path / "other.pt")
    with pytest.raises(LoosefitInputError, match="fingerprint"):
        inf.load_animation_model(out / "model.pt", generative=tmp_path / "other.pt")


def test_a_diverging_rollout_names_the_frame(trained, toy_dataset):
    out, _ = trained
    model = inf.load_animation_model(out / "model.pt")
    motion = DatasetReader(toy_dataset).read("c").motion
    with torch.no_grad():
        model.encoder.fc.bias.fill_(1e6)  # a broken network
    from loosefit.inference.rollout import RolloutError

    with pytest.raises(RolloutError, match="preroll frame 0"):
        model.animate(motion)


def test_train_animate_and_evaluate_commands(toy_dataset, tmp_path):
    from loosefit.cli import main

    gen_run, run = tmp_path / "gen", tmp_path / "motion"
    data = ["--data", str(toy_dataset), "--preset", "cpu", "--epochs", "1", "--max-frames", "8"]
    assert main(["train", "generative", *data, "--out", str(gen_run)]) == 0
    gen = str(gen_run / "checkpoint.pt")
    assert main(["train", "motion", *data, "--generative", gen, "--out", str(run), "--mirror"]) == 0
    assert (run / "model.pt").is_file() and (run / "rest_state.npy").is_file()
    assert torch.load(run / "model.pt", weights_only=False)["config"]["mirror"] is True

    out = tmp_path / "anim"
    args = ["animate", str(run / "model.pt"), "mirror:sway", "--frames", "150", "--out", str(out)]
    assert main(args) == 0
    seq = GarmentSequence.load(next(out.glob("*.npz")))
    assert seq.garment_vertices.shape == (150, DatasetReader(toy_dataset).template.num_vertices, 3)
    assert np.isfinite(seq.garment_vertices).all()

    ev = tmp_path / "eval"
    assert (
        main(
            [
                "evaluate",
                "--checkpoint",
                str(run / "model.pt"),
                "--data",
                str(toy_dataset),
                "--horizons",
                "4,8",
                "--out",
                str(ev),
            ]
        )
        == 0
    )
    for name in ("evaluation.md", "evaluation.csv", "evaluation.json", "rmse_per_frame.png"):
        assert (ev / name).is_file(), name
    assert "iter-8" in (ev / "evaluation.md").read_text()
    # The generative checkpoint where the motion one belongs: a clear error, exit 2.
    assert main(["animate", gen, "sway", "--out", str(tmp_path / "x")]) == 2
    assert not (tmp_path / "x").exists()

    # its engine tier, trained from the command line, beside it, and exported from it
    eng = tmp_path / "engine"
    engine_args = ["--basis", "4", "--targets", "rollout", "--membrane-weight", "10"]
    assert (
        main(
            [
                "train",
                "engine",
                *data,
                "--motion",
                str(run / "model.pt"),
                *engine_args,
                "--out",
                str(eng),
            ]
        )
        == 0
    )
    tier = torch.load(eng / "engine.pt", weights_only=False)
    assert tier["config"]["targets"] == "rollout" and tier["model_config"]["engine"]["basis"] == 4
    assert (eng / "report.md").is_file()
    onnx = tmp_path / "engine.onnx"
    assert (
        main(
            ["export-model", str(onnx), "--checkpoint", str(eng / "engine.pt"), "--tier", "engine"]
        )
        == 0
    )
    assert onnx.is_file() and onnx.with_suffix(".json").is_file()


def test_package_writes_a_pair_that_loads_and_animates_alike(
    trained, toy_dataset, generative, tmp_path
):
    out, _ = trained
    gout, mout = package_model(out / "model.pt", tmp_path / "shared")
    assert {p.name for p in (tmp_path / "shared").iterdir()} == {"generative.pt", "motion.pt"}
    gdata = torch.load(gout, weights_only=False)
    assert (
        "optimizer" not in gdata
        and gdata["model"]["encoder.convs.0.0.weight"].dtype == torch.float16
    )
    # a packaged set holds the networks' configurations, not the training's
    mdata = torch.load(mout, weights_only=False)
    assert "config" not in gdata and "config" not in mdata and "optimizer" not in mdata
    assert set(mdata["model_config"]) == {"encoder", "rollout"}
    assert gdata["model_config"] == torch.load(generative, weights_only=False)["config"]["model"]
    assert torch.load(mout, weights_only=False)["generative"]["absolute"] is None
    # it says what it was trained on: the data set's name and training clips, no path
    reader = DatasetReader(toy_dataset)
    record = mdata["trained_on"]
    assert record["dataset"] == Path(toy_dataset).name and record["clips"] == reader.split("train")
    assert record["frames"] == sum(reader.read(c).num_frames for c in reader.split("train"))
    assert str(tmp_path) not in str(record)
    from loosefit.api import trained_on

    said = f"the `{Path(toy_dataset).name}` data set ({len(record['clips'])} clips"
    assert trained_on(mout).startswith(said)
    # Moved anywhere, the pair still loads (relative path) and animates like the original.
    moved = tmp_path / "elsewhere"
    (tmp_path / "shared").rename(moved)
    original = inf.load_animation_model(out / "model.pt")
    shared = inf.load_animation_model(moved / "motion.pt")
    motion = DatasetReader(toy_dataset).read(DatasetReader(toy_dataset).split("test")[0]).motion
    a = original.animate(motion).vertices
    b = shared.animate(motion).vertices
    assert np.abs(a - b).max() < 0.01  # metres: half-precision generative weights
    # A motion file without its generative partner is a clear error.
    (moved / "generative.pt").unlink()
    with pytest.raises(LoosefitInputError, match="generative"):
        inf.load_animation_model(moved / "motion.pt")


def test_reference_carries_the_rest_drape_with_the_root(trained, toy_dataset):
    out, _ = trained
    model = inf.load_animation_model(out / "model.pt")
    reader = DatasetReader(toy_dataset)
    motion = reader.read("c").motion
    moved = model.carry_drape(motion).vertices  # (T, V, 3)
    rest = model.rest_state.numpy()
    assert moved.shape == (16, model.template.num_vertices, 3)
    # A rigid copy of the drape in every frame: the same edge lengths, on the root.
    i, j = model.template.faces[:, 0], model.template.faces[:, 1]
    np.testing.assert_allclose(
        np.linalg.norm(moved[:, i] - moved[:, j], axis=-1),
        np.broadcast_to(np.linalg.norm(rest[i] - rest[j], axis=-1), (16, len(i))),
        atol=1e-5,
    )
    offset = moved.mean(1) - motion.root_translation
    np.testing.assert_allclose(
        np.linalg.norm(offset, axis=-1), np.linalg.norm(rest.mean(0)), atol=1e-4
    )
    # Scored like a rollout, and not the rollout's score.
    ref = evaluate_rollouts(model, reader, "test", surface=False, reference=True)
    learned = evaluate_rollouts(model, reader, "test", surface=False)
    assert ref["clips"]["c"]["frames"] == 16 and np.isfinite(ref["rmse_cm"])
    assert ref["rmse_cm"] != learned["rmse_cm"]


def test_oracle_scores_the_generative_models_own_code_of_the_truth(trained, toy_dataset):
    out, _ = trained
    model = inf.load_animation_model(out / "model.pt")
    reader = DatasetReader(toy_dataset)
    oracle = evaluate_rollouts(model, reader, "test", surface=False, oracle=True)
    # The same thing in the root frame, from the training targets (Z* decoded): RMSE is
    # rigid-invariant, so the world-frame score must match.
    (clip,) = prepare_clips(
        reader, "test", model.generative, model.floor_height, model.rollout_config
    )
    with torch.no_grad():
        decoded = model.generative.decode(clip.latent)["vertices"]
    expected = 100 * (decoded - clip.target).pow(2).sum(-1).mean(-1).sqrt()
    np.testing.assert_allclose(
        oracle["clips"][clip.name]["rmse_per_frame_cm"], expected.numpy(), rtol=1e-4, atol=1e-4
    )
    learned = evaluate_rollouts(model, reader, "test", surface=False)
    assert oracle["rmse_cm"] != learned["rmse_cm"]


def test_restarts_reset_the_previous_state_to_the_truth(trained, toy_dataset):
    out, _ = trained
    model = inf.load_animation_model(out / "model.pt")
    seq = DatasetReader(toy_dataset).read("c")
    truth = seq.garment_vertices.astype(np.float32)
    plain = model.animate(seq.motion).vertices
    k = 6
    restarted = model.animate(seq.motion, truth=truth, restart_every=k).vertices
    # Up to the first restart, the same rollout; after it, another one.
    np.testing.assert_array_equal(restarted[:k], plain[:k])
    assert not np.allclose(restarted[k:], plain[k:])
    # Frames k..2k-1 depend on the truth only through its frame k - 1.
    other = truth.copy()
    other[: k - 1] += 0.05
    other[k:] += 0.05
    again = model.animate(seq.motion, truth=other, restart_every=k).vertices
    np.testing.assert_array_equal(again[k : 2 * k], restarted[k : 2 * k])
    other[k - 1] += 0.05
    moved = model.animate(seq.motion, truth=other, restart_every=k).vertices
    assert not np.allclose(moved[k : 2 * k], restarted[k : 2 * k])
    with pytest.raises(ValueError, match="truth"):
        model.animate(seq.motion, truth=truth[:3], restart_every=k)
    # Scored like a rollout: no restart within the clip is the plain rollout's score.
    reader = DatasetReader(toy_dataset)
    score = {
        n: evaluate_rollouts(model, reader, "test", surface=False, restart_every=n)
        for n in (None, 16, k)
    }
    assert score[16]["rmse_cm"] == score[None]["rmse_cm"] != score[k]["rmse_cm"]


def test_noise_on_the_previous_state(toy_dataset, generative, skirt, tmp_path):
    with pytest.raises(LoosefitInputError, match="previous_noise"):
        _config(previous_noise=-0.01)
    kw = dict(epochs=2, previous="teacher")
    _train(toy_dataset, generative, skirt, tmp_path / "a", **kw)
    _train(toy_dataset, generative, skirt, tmp_path / "b", previous_noise=0.03, **kw)
    a, b = (torch.load(tmp_path / r / "checkpoint.pt", weights_only=False)["model"] for r in "ab")
    assert any(not torch.equal(a[k], b[k]) for k in a)  # the noise reaches the training


def test_teacher_schedule_falls_to_its_floor():
    cfg = _config(epochs=10, teacher_fraction=0.5, teacher_end=0.2)
    p = [cfg.teacher_probability(e) for e in range(10)]
    assert p[0] == 1.0 and p[5:] == [0.2] * 5
    assert all(a > b for a, b in zip(p[:5], p[1:6], strict=True))  # falling linearly to the floor
    assert _config(epochs=10).teacher_probability(9) == 0.0  # default: pure rollout at the end
    assert _config(previous="teacher", teacher_end=0.2).teacher_probability(11) == 1.0
    for bad in (dict(teacher_end=-0.1), dict(teacher_start=0.5, teacher_end=0.6)):
        with pytest.raises(LoosefitInputError, match="teacher_end"):
            _config(**bad)


def test_mirrored_clips_are_the_clips_mirrored(trained, toy_dataset):
    from loosefit.motion.mirror import REFLECT, mirror_garment, vertex_twins

    out, _ = trained
    model = inf.load_animation_model(out / "model.pt")
    reader = DatasetReader(toy_dataset)
    args = (reader, "train", model.generative, model.floor_height, model.rollout_config)
    plain, both = prepare_clips(*args), prepare_clips(*args, mirror=True)
    assert [c.name for c in both] == [n for c in plain for n in (c.name, f"{c.name}~mirror")]
    twins = vertex_twins(reader.template.vertices)
    for c, m in zip(both[::2], both[1::2], strict=True):
        # Root frames follow the mirror, so the targets in them are mirrored too.
        np.testing.assert_allclose(
            m.target.numpy(), mirror_garment(c.target.numpy(), twins), atol=1e-4
        )
        np.testing.assert_allclose(m.motion.root_translation, c.motion.root_translation @ REFLECT)
        assert not torch.allclose(m.features, c.features)  # a different dance for the encoder
    with pytest.raises(LoosefitInputError, match="mirror"):
        tm.TrainMotionConfig.preset("cpu", mirror="yes")


def test_membrane_and_bending_terms_train_and_are_recorded(
    toy_dataset, generative, skirt, tmp_path
):
    loss = mw.MotionLossConfig(membrane=20.0, bending=0.5)
    _train(toy_dataset, generative, skirt, tmp_path / "phys", epochs=3, loss=loss)
    history = torch.load(tmp_path / "phys" / "checkpoint.pt", weights_only=False)["history"]
    assert {"membrane", "bending"} <= set(history[0]) and np.isfinite(history[-1]["total"])
    model = inf.load_animation_model(tmp_path / "phys" / "model.pt")
    assert "membrane" in model.physics_terms and "bending" in model.physics_terms
    assert "collision" in model.missing_physics_terms


def test_collision_term_trains_on_the_simulation_s_body_contacts(
    toy_dataset, generative, skirt, tmp_path
):
    loss = mw.MotionLossConfig(collision=30.0)
    _train(toy_dataset, generative, skirt, tmp_path / "touch", epochs=2, loss=loss)
    history = torch.load(tmp_path / "touch" / "checkpoint.pt", weights_only=False)["history"]
    assert "collision" in history[0] and np.isfinite(history[-1]["total"])
    model = inf.load_animation_model(tmp_path / "touch" / "model.pt")
    assert "collision" in model.physics_terms
    with pytest.raises(LoosefitInputError, match="collision"):
        mw.MotionLossConfig(collision=-1.0)


def test_body_contacts_lie_under_each_simulated_vertex_in_its_root_frame(trained, toy_dataset):
    """The collision term's contacts: each clip's own body (a mirrored clip's mirrored),
    in the frame its target is in, so the simulated cloth lies on their outer side."""
    from loosefit.motion.mirror import mirror_garment, vertex_twins

    out, _ = trained
    model = inf.load_animation_model(out / "model.pt")
    reader = DatasetReader(toy_dataset)
    args = (reader, "train", model.generative, model.floor_height, model.rollout_config)
    clips = prepare_clips(*args, mirror=True, contacts=True)
    assert prepare_clips(*args)[0].contacts is None
    for c in clips:
        points, normals = c.contacts
        assert points.shape == normals.shape == c.target.shape
        length = normals.norm(dim=-1)
        near = length > 0
        assert near.float().mean() > 0.3, c.name  # the waist and the legs are within reach
        np.testing.assert_allclose(length[near].numpy(), 1.0, atol=1e-4)
        way = c.target - points
        depth = (way * normals).sum(-1)[near]
        np.testing.assert_allclose(depth.abs().numpy(), way.norm(dim=-1)[near].numpy(), atol=1e-5)
        # the toy cloth swings into a leg here and there; the carried waist never does
        outside = float((depth > -0.005).float().mean())
        assert outside > 0.9 and depth.median() > 0, (c.name, outside)
    twins = vertex_twins(reader.template.vertices)
    for c, m in zip(clips[::2], clips[1::2], strict=True):
        # the body is symmetric to millimetres: the mirrored clip's contacts are the
        # clip's, mirrored, where both have one
        both = (c.contacts[1].norm(dim=-1) > 0)[:, twins] & (m.contacts[1].norm(dim=-1) > 0)
        mirrored = mirror_garment(c.contacts[0].numpy(), twins)
        gap = np.linalg.norm(m.contacts[0].numpy() - mirrored, axis=-1)[both.numpy()]
        assert np.median(gap) < 0.005, (c.name, np.median(gap))


def test_flare_term_trains_and_pulls_the_hem_out(toy_dataset, generative, skirt, tmp_path):
    loss = mw.MotionLossConfig(flare=5.0)
    _train(toy_dataset, generative, skirt, tmp_path / "flare", epochs=3, loss=loss)
    history = torch.load(tmp_path / "flare" / "checkpoint.pt", weights_only=False)["history"]
    assert "flare" in history[0] and np.isfinite(history[-1]["total"])
    with pytest.raises(LoosefitInputError, match="flare"):
        mw.MotionLossConfig(flare=-1.0)


def test_warm_start_from_a_packaged_encoder(trained, toy_dataset, generative, skirt, tmp_path):
    run, _ = trained
    package_model(run / "model.pt", tmp_path / "pack")  # half precision, as shipped
    _train(
        toy_dataset,
        generative,
        skirt,
        tmp_path / "fine",
        epochs=1,
        lr=0.0,
        init=str(tmp_path / "pack" / "motion.pt"),
    )
    src = torch.load(tmp_path / "pack" / "motion.pt", weights_only=False)["model"]
    got = torch.load(tmp_path / "fine" / "checkpoint.pt", weights_only=False)["model"]
    assert all(torch.equal(src[k].float(), got[k].float().half().float()) for k in src)
    with pytest.raises(LoosefitInputError, match="model_config.encoder"):
        other = MotionEncoderConfig(motion_fc=16, gru=32)
        _train(
            toy_dataset,
            generative,
            skirt,
            tmp_path / "other",
            epochs=1,
            model=other,
            init=str(run / "model.pt"),
        )


def test_rollouts_start_from_the_data_set_s_recorded_drape(
    toy_dataset, generative, skirt, tmp_path
):
    import shutil

    data = tmp_path / "ds"
    shutil.copytree(toy_dataset, data)
    drape = skirt.vertices + np.float32(0.002)  # what the simulator settled
    np.save(data / "rest_drape.npy", drape)
    cfg = _config(epochs=1)
    tm.train_motion(data, generative, tmp_path / "run", cfg, log=lambda *_: None, progress=False)
    model = inf.load_animation_model(tmp_path / "run" / "model.pt")
    np.testing.assert_array_equal(model.rest_state.numpy(), drape)
    assert not (tmp_path / "run" / "rest_state.npy").exists()  # nothing settled again


def test_a_data_set_without_a_drape_needs_one_given_or_a_way_to_settle_it(
    toy_dataset, generative, tmp_path
):
    with pytest.raises(LoosefitInputError, match=r"rest_drape\.npy.*settle="):
        tm.train_motion(
            toy_dataset,
            generative,
            tmp_path / "run",
            _config(epochs=1),
            log=lambda *_: None,
            progress=False,
        )
    calls = []

    def settle(reader, fps):
        calls.append(fps)
        return torch.from_numpy(reader.template.vertices)

    tm.train_motion(
        toy_dataset,
        generative,
        tmp_path / "run2",
        _config(epochs=1),
        log=lambda *_: None,
        progress=False,
        settle=settle,
    )
    assert len(calls) == 1 and (tmp_path / "run2" / "rest_state.npy").is_file()


def test_evaluate_scores_a_model_against_each_clip_s_members(trained, toy_dataset, tmp_path):
    """`loosefit evaluate --members`: the held-out clip's second simulation (another data
    set of the same clip) gives the ensemble's section; a data set of other cloth is refused
    before any rollout, naming the field."""
    from loosefit.cli import main
    from tests.train.conftest import toy_member

    run, _ = trained
    seed1, manifest = toy_member(toy_dataset, tmp_path / "seed1")
    ev = tmp_path / "eval"
    assert (
        main(
            [
                "evaluate",
                "--checkpoint",
                str(run / "model.pt"),
                "--data",
                str(toy_dataset),
                "--members",
                str(seed1),
                "--rmse-only",
                "--out",
                str(ev),
            ]
        )
        == 0
    )
    result = json.loads((ev / "evaluation.json").read_text())
    clip = result["ensemble"]["clips"]["c"]
    assert clip["members"]["labels"] == ["seed 0", "seed 1"]
    assert clip["members"]["spread_rmse_cm"] == pytest.approx(100 * 0.01 * np.sqrt(3), rel=1e-3)
    (scores,) = clip["models"].values()
    assert len(scores["rmse_to_members_cm"]) == 2 and scores["energy_score_cm"] > 0
    assert "Against an ensemble of simulations" in (ev / "evaluation.md").read_text()

    manifest["config"]["cloth"]["density"] = 0.5
    (seed1 / "manifest.json").write_text(json.dumps(manifest))
    bad = tmp_path / "bad"
    assert (
        main(
            [
                "evaluate",
                "--checkpoint",
                str(run / "model.pt"),
                "--data",
                str(toy_dataset),
                "--members",
                str(seed1),
                "--out",
                str(bad),
            ]
        )
        == 2
    )
    assert not bad.exists()


def test_a_stochastic_engine_tier_gives_one_realisation_a_seed(trained, toy_dataset, tmp_path):
    """`train engine --noise`: trained with the energy score, its noise correlated in time;
    a seed gives the same garment on every run, another seed another plausible one."""
    from loosefit.cli import main
    from loosefit.inference.engine.model import load_engine, rollout_engine

    run, _ = trained
    out = tmp_path / "stochastic"
    args = [
        "train",
        "engine",
        "--data",
        str(toy_dataset),
        "--preset",
        "cpu",
        "--epochs",
        "2",
        "--max-frames",
        "8",
        "--motion",
        str(run / "model.pt"),
        "--basis",
        "4",
        "--noise",
        "2",
        "--noise-correlation",
        "0.9",
        "--samples",
        "2",
        "--out",
        str(out),
    ]
    assert main(args) == 0
    tier = load_engine(out / "engine.pt")
    assert tier.tier.config.noise == 2 and tier.tier.config.noise_correlation == 0.9
    history = torch.load(out / "checkpoint.pt", weights_only=False)["history"]
    assert all(np.isfinite(h["energy"]) and h["energy"] > 0 for h in history)
    motion = load_motion("sway", tier.avatar()).slice(0, 20)
    a, b = rollout_engine(tier, motion, seed=0), rollout_engine(tier, motion, seed=0)
    c = rollout_engine(tier, motion, seed=1)
    np.testing.assert_array_equal(a, b)
    assert np.abs(a - c).max() > 1e-5 and np.isfinite(c).all()
    assert main([*args[:-4], "--samples", "1", "--out", str(tmp_path / "x")]) == 2
    assert not (tmp_path / "x").exists()
    # the graph has no noise input: refused, saying so, before anything is written
    onnx = tmp_path / "stochastic.onnx"
    assert (
        main(
            ["export-model", str(onnx), "--checkpoint", str(out / "engine.pt"), "--tier", "engine"]
        )
        == 2
    )
    assert not onnx.exists()


def test_a_packaged_set_takes_the_residual_process_fitted_beside_it(trained, toy_dataset, tmp_path):
    from loosefit.cli import main

    out, _ = trained
    _, mout = package_model(out / "model.pt", tmp_path / "set")
    args = ["train", "residual", "--motion", str(mout), "--data", str(toy_dataset)]
    assert main([*args, "--directions", "4", "--scale", "2"]) == 0
    assert (tmp_path / "set" / "residual.pt").is_file()
    model = inf.AnimationModel.from_checkpoint(mout)
    assert model.residual is not None and model.residual.config.scale == 2.0

    def animate(*extra: str) -> np.ndarray:
        path = tmp_path / f"anim{'_'.join(extra)}.npz"
        cmd = ["animate", str(mout), "sway", "--frames", "12", "--out", str(path), *extra]
        assert main([*cmd, "--no-collision"]) == 0
        return GarmentSequence.load(path).garment_vertices

    plain, one, again, other = (
        animate(), animate("--realisation", "1"), animate("--realisation", "1"),
        animate("--realisation", "2"),
    )  # fmt: skip
    np.testing.assert_array_equal(one, again)
    assert np.abs(one - plain).max() > 1e-4 and np.abs(one - other).max() > 1e-4
    # a set without a residual process refuses a realisation, naming the file
    (tmp_path / "set" / "residual.pt").rename(tmp_path / "residual.pt")
    with pytest.raises(LoosefitInputError, match="residual"):
        inf.AnimationModel.from_checkpoint(mout).animate(
            DatasetReader(toy_dataset).read("c").motion, realisation=0
        )
    # one fitted to another motion stage is refused, naming the fingerprint; fitting again
    # reads the motion stage alone and writes a new one over it
    stale = torch.load(tmp_path / "residual.pt", weights_only=False)
    stale["fingerprints"]["motion"] = "0" * 16
    torch.save(stale, tmp_path / "set" / "residual.pt")
    with pytest.raises(LoosefitInputError, match="fingerprints.motion"):
        inf.AnimationModel.from_checkpoint(mout)
    assert main([*args, "--directions", "4", "--scale", "2"]) == 0
    assert inf.AnimationModel.from_checkpoint(mout).residual.config.scale == 2.0
