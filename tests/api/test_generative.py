"""A generative model looked at through the API (loosefit.api.generative): a clip's
reconstruction and an interpolation, the same arrays as the model's own calls."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from loosefit.api.generative import open_generative, render_interpolation
from loosefit.errors import LoosefitInputError


@pytest.fixture(scope="module")
def checkpoint(toy_dataset, tmp_path_factory):
    """A small generative model trained for one epoch on the toy data set."""
    from loosefit.api.train import train_generative
    from loosefit.model.generative import GenerativeConfig
    from loosefit.train.generative import TrainGenerativeConfig

    small = GenerativeConfig(uv_size=32, channels=(4, 8, 8, 8), rec_hidden=(16, 16, 16))
    config = TrainGenerativeConfig(model=small, epochs=1, batch_size=8, eval_every=1000)
    run = tmp_path_factory.mktemp("gen") / "run"
    train_generative(config, toy_dataset, run, log=lambda *_: None, progress=False)
    return run / "checkpoint.pt"


def test_a_clip_s_reconstruction_is_the_model_s(checkpoint, toy_dataset):
    from loosefit.eval.metrics import rmse
    from loosefit.inference.checkpoints import load_generative
    from loosefit.model.motion_features import (
        from_root_frame,
        garment_in_root_frame,
        motion_root_frames_of,
    )

    gen = open_generative(checkpoint, toy_dataset)
    assert gen.split("test") == ["c"] and gen.body["floor_height"] == 0.9
    clip = gen.read("c")
    motion, garment = clip.motion.slice(0, 5), clip.garment_vertices[:5]
    rec = gen.reconstruct(motion, garment)
    model, _ = load_generative(checkpoint, gen.template)
    H, p = motion_root_frames_of(motion)
    with torch.no_grad():
        world = from_root_frame(model.reconstruct_all(garment_in_root_frame(motion, garment)), H, p)
    assert np.array_equal(rec.sequence.garment_vertices, world.numpy())
    assert rec.rmse == rmse(world.numpy(), garment) > 0
    assert rec.sequence.num_frames == 5 and rec.sequence.garment is gen.template
    assert rec.sequence.source == f"generative reconstruction {checkpoint.resolve()}"


def test_an_interpolation_runs_between_two_frames_codes(checkpoint, toy_dataset, tmp_path):
    from loosefit.inference.checkpoints import load_generative
    from loosefit.model.motion_features import garment_in_root_frame

    gen = open_generative(checkpoint, toy_dataset)
    a, b = gen.read("a"), gen.read("b")
    line = gen.interpolate((a, 0), (b, 3), steps=3)
    assert line.vertices.shape == (3, gen.template.num_vertices, 3)
    assert np.array_equal(line.alpha, [0.0, 0.5, 1.0]) and line.floor_height == 0.9
    model, _ = load_generative(checkpoint, gen.template)
    ends = [
        garment_in_root_frame(s.motion.slice(f, f + 1), s.garment_vertices[f : f + 1])
        for s, f in ((a, 0), (b, 3))
    ]
    with torch.no_grad():
        mu, _ = model.encode(torch.cat(ends))
        middle = model.decode((0.5 * mu[0] + 0.5 * mu[1])[None])["vertices"]
    np.testing.assert_allclose(line.vertices[1], middle[0].numpy(), atol=1e-6)
    line.save(tmp_path / "line.npz")
    with np.load(tmp_path / "line.npz") as z:
        assert sorted(z.files) == ["alpha", "faces", "vertices"]
        assert np.array_equal(z["vertices"], line.vertices)
    (tmp_path / "r").mkdir()
    try:
        result = render_interpolation(line, tmp_path / "r", title="a -> b", size=32)
    except RuntimeError as exc:
        pytest.skip(f"no headless OpenGL (EGL) context on this machine: {exc}")
    assert result.video.is_file() and len(list((tmp_path / "r" / "frames").glob("*.png"))) == 3


def test_a_missing_checkpoint_is_refused(toy_dataset, tmp_path):
    with pytest.raises(LoosefitInputError):
        open_generative(tmp_path / "missing.pt", toy_dataset)
