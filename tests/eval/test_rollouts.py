"""Scoring rollouts, with a stand-in model whose error is known frame by frame."""

import json
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from loosefit.data.format import DatasetReader
from loosefit.errors import LoosefitInputError
from loosefit.eval.rollouts import evaluate_rollouts
from loosefit.sequence import GarmentSequence


@dataclass
class _Result:
    vertices: np.ndarray
    frames_per_second: float = 50.0


class _Shifted:
    """A model that answers each motion with its simulated garment moved (t + 1) cm along x
    at frame t (so its RMSE at frame t is t + 1 cm); it records how it was asked."""

    path = Path("shifted.pt")

    def __init__(self, template, truths: dict[str, np.ndarray], shift_cm: float = 1.0):
        self.template, self.truths, self.shift_cm, self.calls = template, truths, shift_cm, []

    def _answer(self, motion):
        true = self.truths[motion.name][: motion.num_frames].copy()
        true[..., 0] += self.shift_cm * 0.01 * (np.arange(len(true)) + 1)[:, None]
        return _Result(true)

    def animate(self, motion, truth=None, restart_every=None, stages=None):
        self.calls.append(("animate", restart_every, truth is not None, stages))
        return self._answer(motion)

    def carry_drape(self, motion):
        self.calls.append(("carry_drape",))
        return self._answer(motion)

    def reconstruct(self, motion, true):
        self.calls.append(("reconstruct", len(true)))
        return self._answer(motion)


def _named(reader, name, new_name, frames=None):
    """The dataset's clip ``name`` as a sequence whose motion is called ``new_name``."""
    seq = reader.read(name)
    motion = seq.motion if frames is None else seq.motion.slice(0, frames)
    motion.name = new_name
    return GarmentSequence(
        motion, seq.garment, seq.garment_vertices[: motion.num_frames], seq.avatar, "test"
    )


@pytest.fixture(scope="module")
def reader(toy_dataset):
    return DatasetReader(toy_dataset)


def test_errors_per_clip_per_horizon_and_overall(reader):
    data = {"long": _named(reader, "a", "long"), "short": _named(reader, "b", "short", 10)}
    model = _Shifted(reader.template, {n: s.garment_vertices for n, s in data.items()})
    out = evaluate_rollouts(model, data, horizons=(4, 12, 16), surface=False)
    long, short = out["clips"]["long"], out["clips"]["short"]
    assert (long["frames"], short["frames"]) == (16, 10)
    np.testing.assert_allclose(long["rmse_per_frame_cm"], np.arange(1, 17), rtol=1e-5)
    assert long["rmse_cm"] == pytest.approx(np.sqrt(np.mean(np.arange(1, 17) ** 2)), rel=1e-5)
    assert long["horizons"]["4"] == pytest.approx(np.sqrt(np.mean([1, 4, 9, 16])), rel=1e-5)
    assert set(short["horizons"]) == {"4"}  # 10 frames: no 12-frame horizon
    assert long["horizons"]["16"] == pytest.approx(long["rmse_cm"])  # the whole clip
    assert long["frames_per_second"] == 50.0
    # overall: frame-weighted; a horizon's mean over the clips that reach it
    squares = np.r_[np.arange(1, 17) ** 2, np.arange(1, 11) ** 2]
    assert out["frames"] == 26 and out["split"] == "test"
    assert out["rmse_cm"] == pytest.approx(np.sqrt(squares.mean()), rel=1e-5)
    assert out["horizons"]["4"] == pytest.approx(np.sqrt(np.mean([1, 4, 9, 16])), rel=1e-5)
    assert out["horizons"]["12"] == pytest.approx(long["horizons"]["12"])
    assert "hausdorff_cm" not in out and "sted" not in long


def test_a_perfect_answer_scores_zero_on_the_surface_too(reader):
    data = {"c": _named(reader, "c", "c", 6)}
    model = _Shifted(reader.template, {"c": data["c"].garment_vertices}, shift_cm=0.0)
    out = evaluate_rollouts(model, data)
    assert out["rmse_cm"] == 0.0
    assert out["hausdorff_cm"] == pytest.approx(0.0, abs=1e-4)
    assert out["sted"] == pytest.approx(0.0, abs=1e-9)


def test_the_mode_picks_what_the_model_is_asked(reader):
    data = {"c": _named(reader, "c", "c")}
    model = _Shifted(reader.template, {"c": data["c"].garment_vertices})
    evaluate_rollouts(model, data, surface=False, max_frames=5)
    evaluate_rollouts(model, data, surface=False, reference=True)
    evaluate_rollouts(model, data, surface=False, oracle=True, max_frames=7)
    out = evaluate_rollouts(model, data, surface=False, restart_every=4, stages="mine")
    assert model.calls == [
        ("animate", None, False, None),
        ("carry_drape",),
        ("reconstruct", 7),
        ("animate", 4, True, "mine"),
    ]
    assert out["clips"]["c"]["frames"] == 16


def test_a_dataset_split_scores_one_member_of_each_clip(reader, tmp_path):
    root = tmp_path / "ds"
    shutil.copytree(reader.root, root)
    shutil.copy(root / "sequences" / "c.npz", root / "sequences" / "c@seed1.npz")
    shutil.copy(root / "sequences" / "a.npz", root / "sequences" / "a@seed1.npz")
    manifest = json.loads((root / "manifest.json").read_text())
    manifest["split"]["test"] = ["c", "c@seed1", "a@seed1"]
    (root / "manifest.json").write_text(json.dumps(manifest))
    ensemble = DatasetReader(root)
    truths = {n: ensemble.read(n).garment_vertices for n in ensemble.split("test")}
    out = evaluate_rollouts(_Shifted(ensemble.template, truths), ensemble, surface=False)
    assert sorted(out["clips"]) == ["a@seed1", "c"]  # c's other member is left out


def test_a_model_of_another_garment_is_refused(reader):
    data = {"c": _named(reader, "c", "c")}
    other = reader.template
    other = type(other)(**{**vars(other), "vertices": other.vertices * 1.1})
    with pytest.raises(LoosefitInputError, match="the garment shifted.pt was trained on"):
        evaluate_rollouts(_Shifted(other, {}), data)
    with pytest.raises(LoosefitInputError) as err:
        evaluate_rollouts(_Shifted(other, {}), reader)
    assert err.value.source == str(reader.root / "template.npz")
