"""What the training stages refuse to train on: clips of another garment, avatar or cloth
configuration than their data set's (each error naming both fingerprints)."""

from __future__ import annotations

import json

import pytest

from loosefit.data.format import DatasetReader
from loosefit.errors import LoosefitInputError
from loosefit.garment.fingerprint import garment_fingerprint
from loosefit.inference.timeline import RolloutConfig
from loosefit.sequence import GarmentSequence
from loosefit.train.clips import prepare_clips
from loosefit.train.detail import rollout_pairs
from loosefit.train.frames import prepare_split
from tests.data.test_format import _sequence, _template, make_dataset

# How each stage reads the clips it trains on (nothing else is needed to be refused).
READERS = {
    "generative": lambda reader: prepare_split(reader, "train", None),
    "motion": lambda reader: prepare_clips(reader, "train", None, 0.9, RolloutConfig()),
    "detail": lambda reader: rollout_pairs(None, reader, "train"),
}


def test_training_refuses_a_clip_of_another_garment_naming_both_fingerprints(tmp_path):
    root = make_dataset(tmp_path / "ds")
    other = _template()
    other.vertices = other.vertices + 0.01
    ref = _sequence("s1", 7, 1.0)
    GarmentSequence(ref.motion, other, ref.garment_vertices, ref.avatar, "test").save(
        root / "sequences" / "s1.npz"
    )
    with pytest.raises(LoosefitInputError, match=r"s1\.npz.*another garment") as err:
        READERS["motion"](DatasetReader(root))
    for garment in (_template(), other):
        assert garment_fingerprint(garment.vertices, garment.faces) in str(err.value)


@pytest.mark.parametrize("stage", sorted(READERS))
def test_training_refuses_a_clip_of_another_cloth_configuration(tmp_path, stage):
    root = make_dataset(tmp_path / "ds")
    manifest = json.loads((root / "manifest.json").read_text())
    manifest["config"] = {"cloth": {"substeps": 20}}
    manifest["sequences"] = {"s1": {"cloth_fingerprint": "0123456789abcdef"}}
    (root / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(LoosefitInputError, match=r"manifest\.json.*s1.*0123456789abcdef"):
        READERS[stage](DatasetReader(root))
