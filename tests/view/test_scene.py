from dataclasses import replace

import numpy as np
import pytest

from loosefit.data.format import DatasetReader
from loosefit.errors import LoosefitInputError
from loosefit.sequence import GarmentSequence
from loosefit.view.scene import check_together, from_animated, read_sequences


@pytest.fixture(scope="module")
def reader(toy_dataset):
    return DatasetReader(toy_dataset)


def _copy(seq, frames=None, fps=None, garment=None, shift=0.0):
    motion = seq.motion if frames is None else seq.motion.slice(0, frames)
    if fps is not None:
        motion = replace(motion, fps=fps)
    verts = seq.garment_vertices[: motion.num_frames] + np.float32(shift)
    return GarmentSequence(motion, garment or seq.garment, verts, seq.avatar, "copy")


def test_sequences_of_other_frames_rates_or_garments_are_refused_naming_both(reader):
    a = reader.read("a")
    check_together([a, _copy(a, shift=0.1)], ["x.npz", "y.npz"])
    with pytest.raises(LoosefitInputError) as err:
        check_together([a, _copy(a, frames=10)], ["x.npz", "y.npz"])
    assert err.value.source == "x.npz and y.npz" and err.value.field == "garment_vertices"
    assert (err.value.expected, err.value.found) == ("16 frames (as x.npz)", "10 frames in y.npz")
    with pytest.raises(LoosefitInputError, match="'fps': expected 30 .as x.npz., found 25 in y"):
        check_together([a, _copy(a, fps=25.0)], ["x.npz", "y.npz"])
    other = type(a.garment)(**{**vars(a.garment), "vertices": a.garment.vertices * 1.2})
    with pytest.raises(LoosefitInputError) as err:
        check_together([a, a, _copy(a, garment=other)], ["x", "y", "z"])
    assert err.value.source == "x and z" and err.value.field == "vertices, faces"


def test_files_and_a_data_set_clip_are_read_with_unique_labels(reader, tmp_path):
    a = reader.read("a")
    (tmp_path / "one").mkdir()
    _copy(a, shift=0.01).save(tmp_path / "one" / "run.npz")
    _copy(a, shift=0.02).save(tmp_path / "run.npz")
    data_clip = reader.sequence_path("a")
    seqs, labels, sources = read_sequences(
        [tmp_path / "one" / "run.npz", tmp_path / "run.npz", data_clip],
        data=reader.root,
        clip="a",
    )
    assert labels == ["a (simulation)", "run", "run (2)", "a"]
    assert sources[0] == f"{reader.root}:a" and sources[1] == str(tmp_path / "one" / "run.npz")
    np.testing.assert_array_equal(seqs[0].garment_vertices, a.garment_vertices)
    np.testing.assert_allclose(seqs[2].garment_vertices, a.garment_vertices + 0.02)
    np.testing.assert_array_equal(seqs[3].garment_vertices, a.garment_vertices)


def test_reading_nothing_or_half_a_clip_is_refused(reader):
    with pytest.raises(LoosefitInputError, match="nothing to view"):
        read_sequences([])
    with pytest.raises(LoosefitInputError, match="both --data DATASET and --clip NAME"):
        read_sequences([], data=reader.root)
    with pytest.raises(LoosefitInputError, match="one or more sequences"):
        from_animated([])


def test_sequences_of_one_motion_share_their_posed_body(reader, avatar):
    a, b = reader.read("a"), reader.read("b")
    calls = []
    shown = from_animated(
        [a, _copy(a, shift=0.05), _copy(b)],
        names=["sim", "model", "other"],
        progress=lambda done, total: calls.append((done, total)),
    )
    assert [s.name for s in shown] == ["sim", "model", "other"]
    assert [s.source for s in shown] == ["sequence 1", "sequence 2", "sequence 3"]
    assert shown[0].body is shown[1].body and shown[2].body is not shown[0].body
    assert calls == [(16, 32), (32, 32)]  # two motions posed, 16 frames each
    np.testing.assert_allclose(shown[1].garment, a.garment_vertices + 0.05)
    want = avatar.pose_motion(a.motion).vertices.cpu().numpy()
    np.testing.assert_allclose(shown[0].body, want, atol=1e-5)
    assert shown[0].body_faces.dtype == np.int64 and shown[0].fps == 30.0
    assert shown[0].num_frames == 16
