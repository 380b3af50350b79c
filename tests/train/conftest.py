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
