"""Small trained stages on the toy data, shared by the training tests."""

from __future__ import annotations

import pytest

from loosefit.model.generative import GenerativeConfig
from loosefit.train.generative import TrainGenerativeConfig, train_generative

SMALL = dict(uv_size=32, channels=(4, 8, 8, 8), rec_hidden=(16, 16, 16))


@pytest.fixture(scope="session")
def generative(toy_dataset, tmp_path_factory):
    """A small generative model, trained a little on the toy data."""
    out = tmp_path_factory.mktemp("gen")
    cfg = TrainGenerativeConfig(
        model=GenerativeConfig(**SMALL),
        epochs=15,
        batch_size=8,
        lr=2e-3,
        eval_every=1000,
        checkpoint_every=5,
    )
    train_generative(toy_dataset, out, cfg, log=lambda *_: None, progress=False)
    return out / "checkpoint.pt"


def toy_member(toy_dataset, out):
    """A copy of the toy data set as another seed's simulation of it (seed 1): its test
    clip's garment moved 1 cm in x. Returns the folder and its manifest."""
    import dataclasses
    import json
    import shutil

    from loosefit.data.format import DatasetReader

    shutil.copytree(toy_dataset, out)
    seq = DatasetReader(out).read("c")
    moved = dataclasses.replace(seq, garment_vertices=seq.garment_vertices + 0.01)
    moved.save(out / "sequences" / "c.npz")
    manifest = json.loads((out / "manifest.json").read_text())
    manifest["config"]["seed"] = 1
    (out / "manifest.json").write_text(json.dumps(manifest))
    return out, manifest
