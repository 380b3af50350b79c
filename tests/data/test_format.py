import json

import numpy as np
import pytest
import torch

from loosefit.data.dataset import FrameDataset, WindowDataset, collate_samples
from loosefit.data.format import (
    FORMAT,
    DatasetReader,
    read_sequence,
    write_json_atomic,
    write_sequence,
)
from loosefit.errors import LoosefitInputError
from loosefit.sequence import GarmentSequence
from loosefit.types import GarmentTemplate, Motion

J, V = 3, 6


def _template() -> GarmentTemplate:
    v = np.random.default_rng(0).normal(size=(V, 3))
    f = np.array([[0, 1, 2], [2, 3, 4], [3, 4, 5]])
    uv = np.random.default_rng(1).uniform(0.1, 0.9, size=(V, 2))
    return GarmentTemplate(v, f, uv, f, np.array([0, 1]), name="toy")


def _sequence(name: str, T: int, offset: float = 0.0) -> GarmentSequence:
    rot = np.tile(np.eye(3, dtype=np.float32), (T, J, 1, 1))
    root = np.zeros((T, 3), np.float32) + offset
    motion = Motion(("a", "b", "c"), rot, root, 30.0, name)
    g = np.arange(T * V * 3, dtype=np.float32).reshape(T, V, 3) + offset
    return GarmentSequence(motion, _template(), g, {"rig": "cmu_mb", "shape": {}}, "test")


@pytest.fixture
def dataset(tmp_path):
    return make_dataset(tmp_path / "ds")


def make_dataset(root):
    """Three clips of the toy garment (10, 7 and 12 frames): s0, s1 to train, s2 to test."""
    (root / "sequences").mkdir(parents=True)
    _template().save(root / "template.npz")
    for name, T, off in (("s0", 10, 0.0), ("s1", 7, 1.0), ("s2", 12, 2.0)):
        write_sequence(root / "sequences" / f"{name}.npz", _sequence(name, T, off))
    manifest = {
        "format": FORMAT,
        "complete": True,
        "body": {"model": "anny", "rig": "cmu_mb", "shape": {}, "floor_height": 0.9},
        "split": {"train": ["s0", "s1"], "test": ["s2"]},
    }
    write_json_atomic(root / "manifest.json", manifest)
    return root


def test_round_trip(dataset):
    reader = DatasetReader(dataset)
    seq = reader.read("s1")
    ref = _sequence("s1", 7, 1.0)
    assert np.array_equal(seq.garment_vertices, ref.garment_vertices)
    assert np.array_equal(seq.motion.rotations, ref.motion.rotations)
    assert seq.motion.joint_names == ("a", "b", "c") and seq.motion.fps == 30.0
    assert reader.split("all") == ["s0", "s1", "s2"]
    assert seq.template.name == "toy" and seq.avatar == reader.avatar
    # Plain numpy reads it too, and the API: a clip is an animated garment's file
    d = np.load(dataset / "sequences" / "s1.npz")
    assert d["garment_vertices"].shape == (7, V, 3) and str(d["format"]) == "loosefit.sequence/1"
    same = GarmentSequence.load(dataset / "sequences" / "s1.npz")
    assert np.array_equal(same.garment_vertices, seq.garment_vertices)
    assert not list(dataset.rglob("*partial*")) and not list(dataset.rglob("*.tmp*"))


def test_a_clip_written_before_the_sequence_format_is_still_read(dataset):
    """Data sets simulated before the clips became sequences (the motion's fields and the
    garment alone) read with the data set's template and body."""
    path = dataset / "sequences" / "s1.npz"
    ref = _sequence("s1", 7, 1.0)
    m = ref.motion
    np.savez(
        path,
        joint_names=np.array(m.joint_names),
        rotations=m.rotations,
        root_translation=m.root_translation,
        fps=np.float64(30.0),
        garment_vertices=ref.garment_vertices,
        name=np.array("s1"),
    )
    seq = DatasetReader(dataset).read("s1")
    assert np.array_equal(seq.garment_vertices, ref.garment_vertices)
    assert seq.template.name == "toy" and seq.name == "s1"
    with pytest.raises(LoosefitInputError, match=r"s1\.npz.*format.*through its data set"):
        GarmentSequence.load(path)  # alone, it has no template: the error says where to go


def test_a_clip_of_another_garment_is_refused(dataset):
    other = _template()
    other.vertices = other.vertices + 0.01
    path = dataset / "sequences" / "s0.npz"
    GarmentSequence(
        _sequence("s0", 10).motion, other, _sequence("s0", 10).garment_vertices, {}, "test"
    ).save(path)
    with pytest.raises(LoosefitInputError, match=r"s0\.npz.*another garment") as err:
        DatasetReader(dataset).read("s0")
    # Both fingerprints, to find which data set each clip came from.
    from loosefit.garment.fingerprint import garment_fingerprint

    ours = garment_fingerprint(_template().vertices, _template().faces)
    theirs = garment_fingerprint(other.vertices, other.faces)
    assert ours != theirs and ours in str(err.value) and theirs in str(err.value)


def test_a_clip_on_another_avatar_is_refused_with_both_fingerprints(dataset):
    from loosefit.garment.fingerprint import avatar_fingerprint

    ref = _sequence("s0", 10)
    body = {"rig": "cmu_mb", "shape": {"height": 0.9}}
    GarmentSequence(ref.motion, ref.garment, ref.garment_vertices, body, "test").save(
        dataset / "sequences" / "s0.npz"
    )
    reader = DatasetReader(dataset)
    with pytest.raises(LoosefitInputError, match=r"s0\.npz.*avatar") as err:
        reader.read("s0")
    assert avatar_fingerprint(body) in str(err.value)
    assert avatar_fingerprint(reader.avatar) in str(err.value)
    reader.read("s1")  # the others are the data set's


def test_frame_and_window_datasets(dataset):
    reader = DatasetReader(dataset)
    frames = FrameDataset(reader, "train")
    assert len(frames) == 17
    s = frames[12]  # sequence s1, frame 2
    assert s.sequence == 1 and s.frame == 2
    assert torch.equal(s.garment, torch.from_numpy(_sequence("s1", 7, 1.0).garment_vertices[2]))
    batch = collate_samples([frames[0], frames[5]])
    assert batch.garment.shape == (2, V, 3) and batch.rotations.shape == (2, J, 3, 3)
    windows = WindowDataset(reader, "train", window=5, stride=2)
    assert len(windows) == 3 + 2  # s0: starts 0,2,4; s1: 0,2
    w = windows[4]
    assert w.garment.shape == (5, V, 3) and w.sequence == 1 and w.frame == 2
    with pytest.raises(LoosefitInputError, match="at least one sequence of 20 frames"):
        WindowDataset(reader, "train", window=20)


def _rewrite(path, **changes):
    d = dict(np.load(path))
    d.update(changes)
    for k in [k for k, v in changes.items() if v is None]:
        del d[k]
    np.savez(path, **d)


def test_wrong_vertex_count_names_file_and_field(dataset):
    path = dataset / "sequences" / "s0.npz"
    _rewrite(path, garment_vertices=np.zeros((10, V + 1, 3), np.float32))
    with pytest.raises(LoosefitInputError, match=rf"s0\.npz.*garment_vertices.*\(10, {V}, 3\)"):
        DatasetReader(dataset).read("s0")


def test_nan_names_file_and_field(dataset):
    path = dataset / "sequences" / "s0.npz"
    g = np.zeros((10, V, 3), np.float32)
    g[4, 2, 0] = np.nan
    _rewrite(path, garment_vertices=g)
    with pytest.raises(LoosefitInputError, match=r"s0\.npz.*garment_vertices.*NaN.*\(4, 2, 0\)"):
        read_sequence(path, _template())


def test_wrong_dtype_and_missing_field(dataset):
    path = dataset / "sequences" / "s1.npz"
    _rewrite(path, garment_vertices=np.zeros((7, V, 3), np.float64))
    with pytest.raises(LoosefitInputError, match="float32"):
        read_sequence(path)
    _rewrite(path, rotations=None)
    with pytest.raises(LoosefitInputError, match=r"s1\.npz.*rotations.*missing"):
        read_sequence(path)


def test_mismatched_rotations(dataset):
    path = dataset / "sequences" / "s2.npz"
    _rewrite(path, rotations=np.zeros((12, J, 3, 3), np.float32))
    with pytest.raises(LoosefitInputError, match=r"s2\.npz.*rotations.*orthonormal"):
        read_sequence(path)


def test_incomplete_or_foreign_dataset_is_rejected(dataset, tmp_path):
    m = json.loads((dataset / "manifest.json").read_text())
    m["complete"] = False
    write_json_atomic(dataset / "manifest.json", m)
    with pytest.raises(LoosefitInputError, match="unfinished"):
        DatasetReader(dataset)
    assert DatasetReader(dataset, allow_incomplete=True).split("test") == ["s2"]
    with pytest.raises(LoosefitInputError, match="no manifest"):
        DatasetReader(tmp_path)
    m["format"] = "something/9"
    write_json_atomic(dataset / "manifest.json", m)
    with pytest.raises(LoosefitInputError, match="format"):
        DatasetReader(dataset)


def _with_cloth(root, fingerprints: dict) -> dict:
    """The manifest with a cloth configuration and clip entries of these fingerprints."""
    from loosefit.garment.fingerprint import cloth_fingerprint

    manifest = json.loads((root / "manifest.json").read_text())
    manifest["config"] = {"cloth": {"substeps": 20, "device": "cuda:0"}}
    ours = cloth_fingerprint(manifest["config"]["cloth"])
    manifest["sequences"] = {
        n: ({"cloth_fingerprint": fp.replace("OURS", ours)} if fp else {})
        for n, fp in fingerprints.items()
    }
    write_json_atomic(root / "manifest.json", manifest)
    return manifest


def test_a_clip_of_another_cloth_configuration_is_refused_for_training(dataset):
    from loosefit.garment.fingerprint import cloth_fingerprint

    ours = cloth_fingerprint({"substeps": 20, "device": "cpu"})  # the device left out
    _with_cloth(dataset, {"s0": "OURS", "s1": None, "s2": "0123456789abcdef"})
    reader = DatasetReader(dataset)
    reader.check_uniform(["s0", "s1"])  # s1's entry predates the field: the manifest's
    assert reader.training_clips("train") == ["s0", "s1"]
    with pytest.raises(LoosefitInputError) as err:
        reader.check_uniform(["s0", "s2"])
    text = str(err.value)
    assert "manifest.json" in text and "s2" in text and ours in text and "0123456789abcdef" in text
    assert "one garment, avatar and cloth configuration" in text
    with pytest.raises(LoosefitInputError, match="s2"):
        reader.training_clips("test")
    with pytest.raises(LoosefitInputError, match="s2"):
        FrameDataset(reader, "all")
