"""An ensemble's members: gathered across data sets and inside one, and refused where they
differ in more than the seed."""

from __future__ import annotations

from dataclasses import asdict

import numpy as np
import pytest

from loosefit.data.format import FORMAT, write_json_atomic, write_sequence
from loosefit.errors import LoosefitInputError
from loosefit.eval import ensemble_members as em
from loosefit.sequence import GarmentSequence
from loosefit.sim.cloth_config import ClothConfig
from loosefit.types import GarmentTemplate, Motion

V, J = 40, 3


def _template() -> GarmentTemplate:
    v = np.random.default_rng(0).normal(size=(V, 3))
    f = np.array([[0, 1, 2], [2, 3, 4], [3, 4, 5]])
    uv = np.random.default_rng(1).uniform(0.1, 0.9, size=(V, 2))
    return GarmentTemplate(v, f, uv, f, np.array([0, 1]), name="toy")


def _sequence(frames: int, shift: float, turn: float = 0.0) -> GarmentSequence:
    rot = np.tile(np.eye(3, dtype=np.float32), (frames, J, 1, 1))
    c, s = np.cos(turn), np.sin(turn)  # joint b turned about Z: entries change by sin(turn)
    rot[:, 1, :2, :2] = [[c, -s], [s, c]]
    motion = Motion(("a", "b", "c"), rot, np.zeros((frames, 3), np.float32), 30.0, "m")
    g = np.tile(_template().vertices.astype(np.float32), (frames, 1, 1)) + shift
    return GarmentSequence(motion, _template(), g, {"rig": "cmu_mb", "shape": {}}, "test")


def _dataset(root, seed: int, clips: dict, cloth: dict | None = None):
    """A data set of the toy garment: clips name -> sequence, all held out."""
    (root / "sequences").mkdir(parents=True)
    _template().save(root / "template.npz")
    for name, seq in clips.items():
        write_sequence(root / "sequences" / f"{name}.npz", seq)
    manifest = {
        "format": FORMAT,
        "complete": True,
        "config": {
            "seed": seed,
            "cloth": {**asdict(ClothConfig.tiny()), "seed": seed, **(cloth or {})},
        },
        "body": {"model": "anny", "rig": "cmu_mb", "shape": {}, "floor_height": 0.9},
        "sequences": {n: {"status": "done", "seed": seed} for n in clips},
        "split": {"train": [], "test": list(clips)},
    }
    write_json_atomic(root / "manifest.json", manifest)
    return root


def test_members_gather_across_data_sets_and_inside_one(tmp_path):
    corpus = _dataset(
        tmp_path / "corpus",
        0,
        {"chain_x_y": _sequence(10, 0.0), "z": _sequence(8, 0.0), "z@seed5": _sequence(8, 0.02)},
    )
    other = _dataset(tmp_path / "seed1", 1, {"x_y": _sequence(7, 0.01), "z": _sequence(8, 0.01)})
    ens = em.gather_ensembles([corpus, other])
    assert set(ens) == {"chain_x_y", "z"}
    chain = ens["chain_x_y"]
    assert [m.seed for m in chain.members] == [0, 1]
    assert chain.frames == 7  # scored on the frames the members share
    assert chain.vertices().shape == (2, 7, V, 3)
    assert sorted(m.seed for m in ens["z"].members) == [0, 1, 5]


def test_members_that_differ_in_more_than_the_seed_are_refused(tmp_path):
    corpus = _dataset(tmp_path / "corpus", 0, {"c": _sequence(6, 0.0)})
    stiff = _dataset(tmp_path / "stiff", 1, {"c": _sequence(6, 0.01)}, cloth={"stretch_ke": 123.0})
    with pytest.raises(LoosefitInputError) as err:
        em.gather_ensembles([corpus, stiff])
    assert "config.cloth.stretch_ke" in str(err.value) and "123.0" in str(err.value)
    moved = _dataset(tmp_path / "moved", 1, {"c": _sequence(6, 0.01, turn=0.2)})
    with pytest.raises(LoosefitInputError, match="motion.rotations"):
        em.gather_ensembles([corpus, moved])
    # within the tolerance: the pose correction rounding an arm differently
    near = _dataset(tmp_path / "near", 1, {"c": _sequence(6, 0.01, turn=0.02)})
    assert em.gather_ensembles([corpus, near])["c"].motion_difference == pytest.approx(
        0.02, abs=1e-3
    )
    twin = _dataset(tmp_path / "twin", 0, {"c": _sequence(6, 0.01)})
    with pytest.raises(LoosefitInputError, match="one member per seed"):
        em.gather_ensembles([corpus, twin])
