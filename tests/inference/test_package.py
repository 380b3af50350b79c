"""A trained model as one folder to share: what a packaged stage keeps, and a packaged set
packaged again loads and animates as the set itself. (Packaging a training run:
tests/train/test_motion.py, tests/train/test_detail.py.)"""

from __future__ import annotations

import numpy as np
import torch

import loosefit
from loosefit.inference.checkpoints import DETAIL_FORMAT, MOTION_FORMAT, load_torch
from loosefit.inference.package import describe_training, package_detail, package_model, packed
from tests.conftest import WITH_DETAIL


def test_a_packaged_stage_keeps_its_format_config_weights_and_ties_only():
    data = {
        "format": DETAIL_FORMAT,
        "model_config": {"latent": 8},
        "model": {"w": torch.ones(2), "n": torch.tensor([3])},
        "fingerprints": {"motion": "a", "garment": "b"},
        "motion_checkpoint": {"relative": "motion.pt"},
        "epoch": 4,
        "config": {"lr": 1e-3},  # the training configuration: not shared
        "optimizer": {"state": 1},  # nor the optimiser's state
    }
    out = packed(data)
    assert set(out) == {
        "format",
        "model_config",
        "model",
        "fingerprints",
        "motion_checkpoint",
        "epoch",
    }
    assert out["model"]["w"].dtype == torch.float16  # half precision
    assert out["model"]["n"].dtype == torch.int64  # integers as they were


def test_a_packaged_set_packaged_again_animates_alike(tmp_path):
    files = package_model(WITH_DETAIL / "motion.pt", tmp_path)
    files = [*files, package_detail(WITH_DETAIL / "detail.pt", tmp_path)]
    assert sorted(f.name for f in files) == ["detail.pt", "generative.pt", "motion.pt"]
    motion = load_torch(tmp_path / "motion.pt")
    assert motion["format"] == MOTION_FORMAT and "config" not in motion
    assert motion["generative"]["relative"] == "generative.pt"  # no path of this machine
    a = loosefit.load(WITH_DETAIL).animate("sway", frames=4)
    b = loosefit.load(tmp_path).animate("sway", frames=4)
    np.testing.assert_array_equal(a.vertices, b.vertices)


def test_what_a_model_was_trained_on_in_words():
    assert describe_training(None) == "a data set it does not record"
    record = {"dataset": "salsa", "clips": ["a", "b"], "frames": 1234, "mirrored": True}
    assert describe_training(record) == (
        "the `salsa` data set (2 clips, 1,234 frames, and their mirror images)"
    )
    record = {**record, "mirrored": False, "started_from": "dance"}
    assert describe_training(record) == (
        "the `salsa` data set (2 clips, 1,234 frames), fine-tuned from the `dance` set"
    )
