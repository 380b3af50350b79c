"""Data sets and the viewer through the API (loosefit.api.data)."""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.api.data import pack_dataset, unpack_dataset, viewer_colourings, viewer_config
from loosefit.errors import LoosefitInputError


def test_a_packed_data_set_unpacks_to_the_same_clips(toy_dataset, tmp_path):
    from loosefit.data.format import DatasetReader

    seen = []
    report = pack_dataset(toy_dataset, tmp_path / "toy.pack", progress=lambda d, t: seen.append(d))
    assert report.paths == [tmp_path / "toy.pack"] and seen
    back = unpack_dataset(tmp_path / "toy.pack", tmp_path / "again")
    before, after = DatasetReader(toy_dataset), DatasetReader(back.dest)
    assert before.split("all") == after.split("all")
    for name in before.split("all"):
        a, b = before.read(name), after.read(name)
        np.testing.assert_array_equal(a.motion.rotations, b.motion.rotations)
        assert np.abs(a.garment_vertices - b.garment_vertices).max() <= report.step / 2 + 1e-6


def test_the_viewer_s_settings_are_checked_before_anything_is_posed():
    assert viewer_config(2, colouring="error", reference=1).reference == 1
    with pytest.raises(LoosefitInputError, match="colouring"):
        viewer_config(1, colouring="error")  # nothing to measure the distance to
    with pytest.raises(LoosefitInputError, match="layout"):
        viewer_config(2, layout="stacked")


def test_the_viewer_s_colourings_are_its_config_s_and_a_copy():
    from loosefit.view.config import COLOURINGS

    names = viewer_colourings()
    assert names == COLOURINGS and "error" in names
    names["mine"] = "mine"  # the caller's own copy
    assert "mine" not in viewer_colourings()
