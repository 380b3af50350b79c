"""The settled drape for data sets that do not record it: the settle phase run again with the
data set's own cloth, the very drape the simulator recorded; a manifest without the cloth is
refused naming the file and the field."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from loosefit.data.format import DatasetReader
from loosefit.errors import LoosefitInputError
from loosefit.sim.rest_drape import settled_rest_drape


@pytest.mark.heavy  # reads a simulated data set (the session's tiny one)
def test_the_drape_settled_again_is_the_one_the_simulator_recorded(tiny_simulated):
    reader = DatasetReader(tiny_simulated)
    recorded = reader.rest_drape
    assert recorded is not None
    from loosefit.sim.workers import one_torch_thread

    with one_torch_thread():  # as the simulator settled it: one thread, the same sums
        again = settled_rest_drape(reader, float(reader.manifest["config"]["fps"]))
    assert again.shape == (reader.template.num_vertices, 3) and again.dtype.is_floating_point
    # the same machine, inputs and steps: the same numbers (tests/sim/test_generate.py)
    np.testing.assert_allclose(again.numpy(), recorded, atol=1e-6)
    assert np.abs(recorded - reader.template.vertices).max() > 1e-3  # settled, not the template


def test_a_manifest_without_the_cloth_is_refused_naming_it(toy_dataset, tmp_path):
    root = tmp_path / "ds"
    shutil.copytree(toy_dataset, root)
    manifest = json.loads((root / "manifest.json").read_text())
    del manifest["config"]["cloth"]
    (root / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(
        LoosefitInputError, match=r"manifest\.json: field 'config\.cloth'.*found none"
    ):
        settled_rest_drape(DatasetReader(root), 30.0)
