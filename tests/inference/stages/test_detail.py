"""The detail stage: the network's residual is added in each frame's root frame."""

from __future__ import annotations

import math

import torch

from loosefit.inference.stages import StageFrames
from loosefit.inference.stages.detail import DetailStage


def _frames() -> StageFrames:
    c, s = math.cos(math.pi / 2), math.sin(math.pi / 2)
    H = torch.tensor([[[1.0, 0, 0], [0, 1, 0], [0, 0, 1]], [[c, -s, 0], [s, c, 0], [0, 0, 1]]])
    p = torch.tensor([[0.0, 0.0, 0.0], [2.0, 1.0, 0.5]])
    v = torch.tensor([[[1.0, 0, 0], [0, 1, 0]], [[2.0, 2.0, 0.5], [1.0, 1.0, 0.5]]])
    return StageFrames(
        vertices=v, codes=torch.arange(4.0).reshape(2, 2), headings=H, origins=p, start=7
    )


def test_the_residual_is_taken_in_the_root_frame():
    seen = {}

    def network(local, codes):
        seen["local"], seen["codes"] = local.clone(), codes.clone()
        return torch.tensor([0.1, 0.0, 0.0]).expand_as(local)  # along the root's own x

    frames = _frames()
    out = DetailStage(network)(frames)
    # the garments the network sees: each frame's world garment in its root frame, by hand
    want_local = torch.tensor([[[1.0, 0, 0], [0, 1, 0]], [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])
    torch.testing.assert_close(seen["local"], want_local, atol=1e-6, rtol=0)
    torch.testing.assert_close(seen["codes"], frames.codes)
    # +0.1 along the root's x: world x in the first frame, world y in the second (turned 90 deg)
    want = frames.vertices.clone()
    want[0, :, 0] += 0.1
    want[1, :, 1] += 0.1
    torch.testing.assert_close(out, want, atol=1e-6, rtol=0)
    assert out.device.type == "cpu" and DetailStage.name == "detail"


def test_a_zero_residual_gives_the_garments_back():
    frames = _frames()
    out = DetailStage(lambda local, codes: torch.zeros_like(local))(frames)
    torch.testing.assert_close(out, frames.vertices, atol=1e-6, rtol=0)
