"""``loosefit reconstruct`` / ``interpolate``: a generative model's commands; a frame of a
clip as CLIP:FRAME."""

from __future__ import annotations

import pytest

from loosefit.cli import build_parser
from loosefit.cli.generative import _frame_ref
from loosefit.errors import LoosefitInputError


def test_a_frame_is_clip_colon_frame():
    assert _frame_ref("dance_000:40", ["dance_000", "b"], "--a") == ("dance_000", 40)
    assert _frame_ref("mirror:a:3", ["mirror:a"], "--a") == ("mirror:a", 3)  # the last colon
    with pytest.raises(LoosefitInputError, match=r"--a.*CLIP:FRAME.*'dance_000'"):
        _frame_ref("dance_000", ["dance_000"], "--a")
    with pytest.raises(LoosefitInputError, match=r"--b.*one of \['a'\].*'c'"):
        _frame_ref("c:1", ["a"], "--b")


def test_the_commands_need_a_checkpoint():
    p = build_parser()
    args = p.parse_args(["interpolate", "--checkpoint", "g.pt", "--a", "x:1", "--b", "y:2"])
    assert (args.steps, args.size, args.data) == (8, 384, "datasets/demo")
    with pytest.raises(SystemExit):
        p.parse_args(["reconstruct"])
