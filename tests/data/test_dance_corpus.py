"""The shared dance corpus (../shared/datasets/dance.lfz.*) reads as a loosefit data set.

It is unpacked once per session (a few seconds), unless the repository's datasets/dance
holds it complete already.
"""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.data.format import DatasetReader
from tests.data.conftest import needs_corpus

pytestmark = needs_corpus
CHAIN = "chain_60_03_60_07_61_03_61_07"  # the held-out salsa chain


@pytest.fixture(scope="module")
def reader(dance_dataset):
    return DatasetReader(dance_dataset)


def test_the_split_holds_16_clips_to_train_and_4_held_out(reader):
    train, test = reader.split("train"), reader.split("test")
    assert len(train) == 16 and len(test) == 4
    assert "60_01" in train and CHAIN in test and "05_02" in test
    assert reader.training_clips("train") == train  # one cloth configuration (no fingerprints)
    assert reader.template.num_vertices == 2352


@pytest.mark.parametrize("name", ["60_01", CHAIN, "05_02"])
def test_a_clip_reads_whole(reader, name):
    seq = reader.read(name)
    frames = reader.manifest["sequences"][name]["frames"]
    assert seq.num_frames == frames == seq.motion.num_frames
    assert seq.garment_vertices.shape == (frames, 2352, 3)
    assert seq.garment_vertices.dtype == np.float32
    assert np.isfinite(seq.garment_vertices).all() and np.isfinite(seq.motion.rotations).all()
    if name == CHAIN:
        assert frames == 1957
