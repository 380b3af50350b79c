"""Scoring and diagnosing through the API (loosefit.api.evaluate): the same figures and
files as the scorers called directly, with a stand-in model whose error is known; the
refusals before any work."""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from loosefit.api.evaluate import diagnose_clip, evaluate, open_clip, open_evaluation
from loosefit.errors import LoosefitInputError


@dataclass
class _Result:
    vertices: np.ndarray
    frames_per_second: float = 50.0


class _Shifted:
    """A model that answers each motion with its simulated garment moved (t + 1) cm along x
    at frame t."""

    path = Path("runs/shifted/model.pt")

    def __init__(self, template, truths: dict[str, np.ndarray]):
        self.template, self.truths = template, truths

    def animate(self, motion, stages=None):
        true = self.truths[motion.name][: motion.num_frames].copy()
        true[..., 0] += 0.01 * (np.arange(len(true)) + 1)[:, None]
        return _Result(true)


@pytest.fixture(scope="module")
def model(toy_dataset):
    from loosefit.data.format import DatasetReader

    reader = DatasetReader(toy_dataset)
    seqs = [reader.read(n) for n in reader.split("all")]
    return _Shifted(reader.template, {s.motion.name: s.garment_vertices for s in seqs})


@pytest.fixture(scope="module")
def members(toy_dataset, tmp_path_factory):
    """The toy data set's clips simulated again from another seed (the garment 1 cm up)."""
    from loosefit.data.format import read_any_sequence, write_sequence

    root = tmp_path_factory.mktemp("members") / "seed1"
    shutil.copytree(toy_dataset, root)
    manifest = json.loads((root / "manifest.json").read_text())
    manifest["config"]["seed"] = manifest["config"]["cloth"]["seed"] = 1
    (root / "manifest.json").write_text(json.dumps(manifest))
    for path in (root / "sequences").glob("*.npz"):
        seq = read_any_sequence(path)
        seq.garment_vertices = seq.garment_vertices + np.float32([0, 0, 0.01])
        write_sequence(path, seq)
    return root


def test_rollouts_score_as_the_scorer_does(model, toy_dataset):
    from loosefit.data.format import DatasetReader
    from loosefit.eval.rollouts import evaluate_rollouts

    evaluation = open_evaluation(model, toy_dataset)
    assert evaluation.members is None and evaluation.name == "shifted"
    got = evaluation.rollouts(horizons=(4, 8), surface=False, max_frames=12, threads=1)
    want = evaluate_rollouts(
        model, DatasetReader(toy_dataset), "test", horizons=(4, 8), surface=False, max_frames=12
    )
    assert got == {
        **want,
        "checkpoint": str(Path("runs/shifted/model.pt").resolve()),
        "dataset": str(toy_dataset.resolve()),
    }
    np.testing.assert_allclose(got["clips"]["c"]["rmse_per_frame_cm"], np.arange(1, 13), rtol=1e-5)


def test_sequences_are_scored_by_their_names(model, toy_dataset):
    files = [toy_dataset / "sequences" / f"{n}.npz" for n in ("a", "b")]
    got = open_evaluation(model, [str(f) for f in files]).rollouts(surface=False)
    assert list(got["clips"]) == ["a", "b"]
    assert got["dataset"] == [str(f.resolve()) for f in files]


def test_members_need_a_data_set(model, toy_dataset):
    seq = toy_dataset / "sequences" / "a.npz"
    with pytest.raises(LoosefitInputError, match="a data set folder to gather members with"):
        open_evaluation(model, [seq], members=[toy_dataset])
    with pytest.raises(LoosefitInputError, match="members"):
        open_evaluation(model, toy_dataset).ensemble()  # no clip has any


def test_the_ensemble_and_the_report_are_the_scorers(model, toy_dataset, members, tmp_path):
    from loosefit.data.format import DatasetReader
    from loosefit.eval.ensemble import evaluate_ensemble
    from loosefit.eval.ensemble_members import gather_ensembles
    from loosefit.eval.report import write_rollout_report
    from loosefit.eval.rollouts import evaluate_rollouts

    lines = []
    got = evaluate(
        model,
        toy_dataset,
        members=[members],
        surface=False,
        out=tmp_path / "api",
        progress=lines.append,
    )
    sources = [toy_dataset, members]
    want = evaluate_rollouts(model, DatasetReader(toy_dataset), surface=False)
    want["checkpoint"] = str(model.path.resolve())
    want["dataset"] = str(toy_dataset.resolve())
    want["ensemble"] = evaluate_ensemble(
        {"shifted": model}, sources, surface=False, ensembles=gather_ensembles(sources)
    )
    assert json.dumps(got) == json.dumps(want)
    assert list(got["ensemble"]["clips"]) == ["c"] and lines == ["c: shifted on 16 frames"]
    write_rollout_report(want, tmp_path / "direct", "Rollouts of shifted")
    for name in ("evaluation.md", "evaluation.csv", "evaluation.json"):
        assert (tmp_path / "api" / name).read_bytes() == (tmp_path / "direct" / name).read_bytes()


def test_a_clip_and_its_collider_s_arms(toy_dataset, tmp_path):
    from loosefit.fitting.place import collider_arms
    from loosefit.inference.model_common import arm_collision_of

    clip = open_clip(toy_dataset, "c")
    config = json.loads((toy_dataset / "manifest.json").read_text())["config"]
    assert clip.arms == arm_collision_of(config, collider_arms(clip.sequence.garment))
    assert (clip.name, clip.source, clip.shape) == ("c", toy_dataset, clip.sequence.avatar["shape"])
    again = open_clip(toy_dataset / "sequences" / "c.npz", arms="upper")  # a data set's file
    assert (again.name, again.arms) == ("c", "upper")
    assert open_clip(toy_dataset, "c", arms="none").arms is False
    with pytest.raises(LoosefitInputError, match="a clip of the data set after it"):
        open_clip(toy_dataset)
    with pytest.raises(LoosefitInputError, match="no clip after a sequence file"):
        open_clip(toy_dataset / "sequences" / "c.npz", "b")
    with pytest.raises(LoosefitInputError, match="auto, none, upper or all"):
        open_clip(toy_dataset, "c", arms="both")


def test_a_diagnosis_is_the_detector_s(toy_dataset, avatar, tmp_path):
    import torch

    from loosefit.body.regions import body_parts
    from loosefit.eval.penetration import diagnose_clip as direct
    from loosefit.eval.penetration import format_events

    clip = open_clip(toy_dataset, "c")
    seen = []
    found = diagnose_clip(
        clip, avatar=avatar, tolerance=0.001, progress=lambda d, t: seen.append((d, t))
    )
    seq = clip.sequence
    with torch.no_grad():
        body = avatar.pose_motion(seq.motion).vertices.float().cpu().numpy()
    parts = body_parts(avatar, clip.arms)
    want = direct(
        seq.garment_vertices, body, seq.motion.rotations[:, 0], seq.fps, parts, tolerance=0.001
    )
    assert json.dumps(found.diagnosis.to_json()) == json.dumps(want.to_json())
    np.testing.assert_array_equal(found.body, body)
    assert found.summary() == f"c: {want.summary()}; arms collide: {clip.arms}"
    assert found.table() == format_events(want.events, 0.001) and "11-15" in found.table()
    assert seen[-1] == (32, 32)  # 16 frames' penetrations, then their motion
    path = found.write_report(tmp_path / "d", [tmp_path / "d" / "x.png"])
    report = json.loads(path.read_text())
    assert report == json.loads(json.dumps(found.to_json([tmp_path / "d" / "x.png"])))
    assert (report["clip"], report["source"], report["renders"]) == (
        "c",
        str(toy_dataset),
        [str(tmp_path / "d" / "x.png")],
    )
    assert found.render_worst(tmp_path / "none", top=0) == []
    with pytest.raises(LoosefitInputError, match="0 < tolerance < 1 m"):
        diagnose_clip(clip, avatar=avatar, tolerance=2.0)


def test_the_worst_frames_are_rendered(toy_dataset, avatar, tmp_path):
    from loosefit.render.renderer import Renderer

    try:
        Renderer().close()
    except RuntimeError as exc:
        pytest.skip(f"no headless OpenGL (EGL) context: {exc}")
    found = diagnose_clip(open_clip(toy_dataset, "c"), avatar=avatar, tolerance=0.001)
    written = []
    paths = found.render_worst(tmp_path, top=1, size=64, written=written.append)
    assert paths == written == [tmp_path / "worst1_frame00014.png"]
    from PIL import Image

    assert Image.open(paths[0]).size[1] >= 64
