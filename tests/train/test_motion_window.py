"""One window of the motion encoder's training: the gradient stays within the window, and
an unrolled window differentiates through the encoder's own fed-back predictions; the speed
term starts at each clip's second motion frame and a window's second."""

from __future__ import annotations

import pytest
import torch

import loosefit.inference.animator as inf
import loosefit.train.motion_window as mw
from loosefit.data.format import DatasetReader
from loosefit.errors import LoosefitInputError
from loosefit.geometry.laplacian import Laplacian
from loosefit.train.clips import prepare_clips, stack_clips
from tests.train.test_motion import _train


@pytest.fixture(scope="module")
def trained(toy_dataset, generative, skirt, tmp_path_factory):
    """A toy motion encoder after one epoch: where a gradient flows does not depend on how
    far it has trained."""
    out = tmp_path_factory.mktemp("window")
    return out, _train(toy_dataset, generative, skirt, out, epochs=1)


def _windows(trained, toy_dataset, skirt):
    """The trained toy model, its training clips stacked (features differentiable), a Laplacian."""
    model = inf.load_animation_model(trained[0] / "model.pt")
    reader = DatasetReader(toy_dataset)
    clips = prepare_clips(
        reader, "train", model.generative, model.floor_height, model.rollout_config
    )
    batch = stack_clips(clips)
    batch["features"] = batch["features"].clone().requires_grad_(True)
    model.encoder.train()
    return model, batch, Laplacian(skirt.faces, skirt.num_vertices)


def _run(model, batch, lap, start: int, stop: int, **kw) -> mw.WindowResult:
    """One window of the toy model from a fresh GRU state and the rest drape (``kw``: the
    rest of :func:`~loosefit.train.motion_window.run_window`'s arguments, teacher 0 and
    the default loss unless given)."""
    kw = {
        "hidden": model.encoder.initial_hidden(2),
        "previous": model.rest_state[None].expand(2, -1, -1),
        "teacher": 0.0,
        "loss": mw.MotionLossConfig(),
        **kw,
    }
    return mw.run_window(model.encoder, model.generative, lap, batch, start, stop, **kw)


def test_truncated_backpropagation_stops_at_the_window(trained, toy_dataset, skirt):
    model, batch, lap = _windows(trained, toy_dataset, skirt)
    enc = model.encoder
    hidden = enc.initial_hidden(2)
    prev = model.rest_state[None].expand(2, -1, -1)
    loss = mw.MotionLossConfig()
    first = mw.run_window(
        enc,
        model.generative,
        lap,
        batch,
        0,
        10,
        hidden=hidden,
        previous=prev,
        teacher=0.0,
        loss=loss,
    )
    second = mw.run_window(
        enc,
        model.generative,
        lap,
        batch,
        10,
        20,
        hidden=first.hidden,
        previous=first.previous,
        teacher=0.0,
        loss=loss,
    )
    (g,) = torch.autograd.grad(second.terms["total"], batch["features"])
    assert g[:, :10].abs().max() == 0  # nothing flows back into the previous window
    assert g[:, 10:20].abs().max() > 0


def test_unrolled_training_differentiates_through_its_own_predictions(trained, toy_dataset, skirt):
    model, batch, lap = _windows(trained, toy_dataset, skirt)

    def grads(teacher: float, unroll: bool, start: int = 0, stop: int = 20):
        window = _run(model, batch, lap, start, stop, teacher=teacher, unroll=unroll)
        assert not window.previous.requires_grad  # the next window starts detached either way
        total = window.terms["total"]
        return total, torch.autograd.grad(total, batch["features"])[0]

    (l0, g0), (l1, g1) = grads(0.0, False), grads(0.0, True)
    assert torch.allclose(l0, l1)  # the same forward pass ...
    assert not torch.allclose(g0, g1)  # ... with gradients through the fed-back predictions
    first = int(batch["preroll"].max())  # ground truth exists from each clip's motion on
    assert first + 10 <= int(batch["length"].min())
    (_, g0), (_, g1) = grads(1.0, False, first, first + 10), grads(1.0, True, first, first + 10)
    assert torch.equal(g0, g1)  # ground truth fed back: nothing to unroll
    _, g = grads(0.0, True, 10, 20)
    assert g[:, :10].abs().max() == 0 and g[:, 10:20].abs().max() > 0  # still within the window


def test_speed_term_starts_at_a_clips_and_a_windows_second_frame(trained, toy_dataset, skirt):
    model, batch, lap = _windows(trained, toy_dataset, skirt)
    P = batch["preroll"]

    def speed(stop: int, start: int = 0) -> torch.Tensor:
        loss = mw.MotionLossConfig(speed=1.0)
        return _run(model, batch, lap, start, stop, loss=loss).terms["speed"]

    # up to the first motion frame: no frame with a truth to step from (it steps from the
    # rest drape, whose truth is no target)
    assert float(speed(int(P.min()) + 1).detach()) == 0.0
    # a window's first frame has no prediction of its own before it in the window
    assert float(speed(int(P.max()) + 5, start=int(P.max()) + 4).detach()) == 0.0
    later = speed(int(P.max()) + 5)
    assert float(later.detach()) > 0
    (g,) = torch.autograd.grad(later, batch["features"])
    assert g.abs().max() > 0  # it trains the encoder
    with pytest.raises(LoosefitInputError, match="speed"):
        mw.MotionLossConfig(speed=-1.0)
