"""The baselines' shared training loop, rollout interface and evaluation, on the toy data."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

import loosefit
from loosefit.data.format import DatasetReader
from loosefit.errors import LoosefitInputError
from loosefit.eval.metrics import hausdorff, rmse_per_frame, sted
from loosefit.eval.rollouts import evaluate_rollouts
from loosefit.inference.baseline import BaselineModel
from loosefit.inference.stages import Stages
from loosefit.model.baselines import BaselineConfig
from loosefit.sequence import GarmentSequence
from loosefit.train import baseline as tb

RAW = Stages(detail=False, lengths=False, collision=False)


def _config(method: str, epochs: int = 6) -> tb.TrainBaselineConfig:
    return tb.TrainBaselineConfig(
        model=BaselineConfig(method=method, motion_fc=16, gru=24, head_hidden=32, bones=4),
        epochs=epochs,
        batch_size=2,
        window=8,
        lr=3e-3,
        eval_every=1000,
        checkpoint_every=2,
        ssdr_iterations=5,
    )


@pytest.fixture(scope="module", params=["santesteban", "virtual-bones"])
def trained(request, toy_dataset, tmp_path_factory):
    out = tmp_path_factory.mktemp(request.param)
    report = tb.train_baseline(
        toy_dataset, out, _config(request.param), log=lambda *_: None, progress=False
    )
    return out, report, BaselineModel.from_checkpoint(out / "model.pt")


def test_training_lowers_the_loss(trained):
    out, report, model = trained
    history = torch.load(out / "checkpoint.pt", weights_only=False)["history"]
    assert history[-1]["total"] < 0.7 * history[0]["total"]
    assert np.isfinite(report["test"]["rmse_cm"]) and report["test"]["frames"] == 16
    assert model.method == report["method"]
    if model.method == "virtual-bones":
        assert (out / "ssdr.npz").is_file() and model.network.influences == 4
    else:
        assert model.network.influences == len(model.joint_names)


def test_evaluation_scores_the_rollout_as_the_same_vertices_given_directly(trained, toy_dataset):
    _, _, model = trained
    reader = DatasetReader(toy_dataset)
    ev = evaluate_rollouts(model, reader, "test", horizons=(4,), stages=RAW)
    (name,) = reader.split("test")
    seq = reader.read(name)
    pred = model.animate(seq.motion, stages=RAW).vertices
    true, faces = seq.garment_vertices, reader.template.faces
    per = 100 * rmse_per_frame(pred, true)
    clip = ev["clips"][name]
    np.testing.assert_allclose(clip["rmse_per_frame_cm"], per, rtol=1e-6)
    assert ev["rmse_cm"] == pytest.approx(float(np.sqrt(np.mean(per**2))), rel=1e-6)
    assert ev["horizons"]["4"] == pytest.approx(float(np.sqrt(np.mean(per[:4] ** 2))), rel=1e-6)
    assert ev["hausdorff_cm"] == pytest.approx(
        100 * float(hausdorff(pred, true, faces).mean()), rel=1e-6
    )
    assert ev["sted"] == pytest.approx(sted(pred, true, faces)["sted"], rel=1e-6)


def test_rollouts_are_deterministic_on_the_motion_and_load_through_the_pipeline(
    trained, toy_dataset
):

    out, _, model = trained
    reader = DatasetReader(toy_dataset)
    motion = reader.read("c").motion
    a = model.animate(motion, stages=RAW)
    b = loosefit.load(out / "checkpoint.pt").model.animate(motion, stages=RAW)
    assert a.vertices.shape == (16, reader.template.num_vertices, 3)
    np.testing.assert_array_equal(a.vertices, b.vertices)
    # the garment is carried by the motion: its centre follows the root
    centre = a.vertices.mean(1)
    root = motion.root_translation
    assert np.abs(centre[:, :2] - root[:, :2]).max() < 0.15


def test_santesteban_post_process_pushes_cloth_out_of_the_body(trained, toy_dataset):
    _, _, model = trained
    if model.method != "santesteban":
        reader = DatasetReader(toy_dataset)
        r = model.animate(reader.read("c").motion)  # no post-process: collision is a no-op
        assert r.collisions is None
        return
    reader = DatasetReader(toy_dataset)
    motion = reader.read("c").motion
    # sink the garment toward the root: vertices end inside the body, then come out
    net = model.network
    with torch.no_grad():
        rest = net.rest.clone()
        net.rest.mul_(0.6)
    try:
        r = model.animate(motion)
    finally:
        with torch.no_grad():
            net.rest.copy_(rest)
    before = sum(c["inside_before"] for c in r.collisions)
    after = sum(c["inside_after"] for c in r.collisions)
    assert before > 0 and after < 0.05 * before
    assert r.decoded is not None and not np.array_equal(r.decoded, r.vertices)


def test_bad_inputs_are_clear_errors(trained, toy_dataset, tmp_path):
    out, _, model = trained
    reader = DatasetReader(toy_dataset)
    motion = reader.read("c").motion
    with pytest.raises(LoosefitInputError, match="restart_every"):
        model.animate(motion, truth=reader.read("c").garment_vertices, restart_every=4)
    bad = motion.slice(0, 4)
    bad.rotations[2, 3] = np.nan
    with pytest.raises(LoosefitInputError, match="finite"):
        model.animate(bad)
    with pytest.raises(LoosefitInputError):
        BaselineModel.from_checkpoint(toy_dataset / "template.npz")
    data = torch.load(out / "model.pt", weights_only=False)
    data["model"]["skin_weights"] = data["model"]["skin_weights"][:, :2]
    torch.save(data, tmp_path / "broken.pt")
    with pytest.raises(LoosefitInputError, match="weights of this baseline"):
        BaselineModel.from_checkpoint(tmp_path / "broken.pt")


def test_train_baseline_evaluate_and_animate_commands(toy_dataset, tmp_path):
    from loosefit.cli import main

    run = tmp_path / "sb"
    assert (
        main(
            [
                "train",
                "baseline",
                "--method",
                "santesteban",
                "--data",
                str(toy_dataset),
                "--preset",
                "cpu",
                "--epochs",
                "1",
                "--max-frames",
                "8",
                "--mirror",
                "--out",
                str(run),
            ]
        )
        == 0
    )
    assert torch.load(run / "model.pt", weights_only=False)["config"]["mirror"] is True
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
                "4",
                "--out",
                str(ev),
            ]
        )
        == 0
    )
    assert "iter-4" in (ev / "evaluation.md").read_text()
    # the ground truth as sequence files (a simulate()'s save(), or a data set's clips)
    ev2 = tmp_path / "eval2"
    assert (
        main(
            [
                "evaluate",
                "--checkpoint",
                str(run / "model.pt"),
                "--data",
                str(toy_dataset / "sequences" / "c.npz"),
                "--horizons",
                "4",
                "--out",
                str(ev2),
            ]
        )
        == 0
    )
    a, b = (json.loads((e / "evaluation.json").read_text()) for e in (ev, ev2))
    assert a["clips"]["c"]["rmse_cm"] == pytest.approx(b["clips"]["c"]["rmse_cm"], rel=1e-6)
    out = tmp_path / "anim"
    assert (
        main(
            [
                "animate",
                str(run / "model.pt"),
                "sway",
                "--frames",
                "20",
                "--out",
                str(out),
                "--export",
                str(tmp_path / "sway.usdc"),
            ]
        )
        == 0
    )
    seq = GarmentSequence.load(out / "sway.npz")
    assert seq.garment_vertices.shape == (20, DatasetReader(toy_dataset).template.num_vertices, 3)
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(tmp_path / "sway.usdc"))
    points = UsdGeom.Mesh(stage.GetPrimAtPath("/loosefit/garment")).GetPointsAttr()
    np.testing.assert_array_equal(
        np.asarray(points.Get(Usd.TimeCode(19))), seq.garment_vertices[19]
    )
    assert (
        main(["train", "baseline", "--data", str(toy_dataset), "--out", str(tmp_path / "x")]) == 2
    )


def test_a_broken_baseline_checkpoint_is_a_clear_error(trained, tmp_path):
    """Fuzzed like every reader (tests/test_fuzz.py): a key deleted or replaced, the file cut."""
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st

    from loosefit.inference.checkpoints import load_torch
    from tests.test_fuzz import accepts, finite

    out, _, _ = trained
    saved = load_torch(out / "model.pt")

    @settings(
        max_examples=30,
        deadline=None,
        derandomize=True,
        suppress_health_check=[HealthCheck.too_slow],
    )
    @given(
        key=st.sampled_from(sorted(saved)),
        how=st.sampled_from(["delete", "value", "cut"]),
        value=st.one_of(
            st.none(),
            st.integers(),
            st.text(max_size=3),
            st.just([1, 2]),
            st.just({"x": 1}),
            st.just(torch.full((2, 2), float("nan"))),
        ),
        cut=st.floats(0.0, 0.99),
    )
    def check(key, how, value, cut):
        path = tmp_path / "broken.pt"
        if how == "cut":
            raw = (out / "model.pt").read_bytes()
            path.write_bytes(raw[: int(cut * len(raw))])
        else:
            data = dict(saved)
            if how == "delete":
                del data[key]
            else:
                data[key] = value
            torch.save(data, path)
        model = accepts(lambda: loosefit.load(path).model)
        if model is not None:
            for p in model.network.parameters():
                finite(p.detach().numpy())

    check()
