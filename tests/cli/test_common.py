"""The flags several commands share and what they parse to: a body's phenotypes, a frame
range, an offset, the stages left on, the thread count; each refusal names its flag."""

from __future__ import annotations

import argparse

import pytest

from loosefit.cli.common import (
    add_stage_args,
    add_threads_arg,
    frame_range,
    offset,
    parse_shape,
    stages,
    threads_of,
)
from loosefit.errors import LoosefitInputError


def test_a_shape_is_names_and_values():
    assert parse_shape("") == {}
    assert parse_shape("gender=0.9, height=0.6,") == {"gender": 0.9, "height": 0.6}
    with pytest.raises(LoosefitInputError, match=r"--shape.*NAME=VALUE.*'height'"):
        parse_shape("height")
    with pytest.raises(LoosefitInputError, match="'weight=heavy'"):
        parse_shape("weight=heavy")


def test_a_frame_range_is_a_slice_of_the_clip():
    args = argparse.Namespace(start_frame=5, max_frames=10)
    assert frame_range(args, 40) == (5, 15)
    assert frame_range(argparse.Namespace(start_frame=0, max_frames=None), 40) == (0, None)
    with pytest.raises(LoosefitInputError, match=r"--start-frame.*0 to 39.*40"):
        frame_range(argparse.Namespace(start_frame=40, max_frames=None), 40)


def test_an_offset_is_three_numbers_in_metres():
    assert offset(None) == (0.0, 0.0, 0.0)
    assert offset("0,0,0.02") == (0.0, 0.0, 0.02)
    with pytest.raises(LoosefitInputError, match=r"--offset.*X,Y,Z.*'1,2'"):
        offset("1,2")


def _parsed(*argv: str) -> argparse.Namespace:
    p = argparse.ArgumentParser()
    add_stage_args(p)
    add_threads_arg(p)
    return p.parse_args(list(argv))


def test_the_stage_flags_switch_stages_off():
    on = stages(_parsed())
    assert (on.detail, on.lengths, on.collision, on.feedback) == (True, True, True, False)
    off = stages(_parsed("--no-detail", "--no-lengths", "--no-collision", "--feedback"))
    assert (off.detail, off.lengths, off.collision, off.feedback) == (False, False, False, True)


def test_threads_are_a_whole_number_of_at_least_one():
    assert threads_of(_parsed()) is None
    assert threads_of(_parsed("--threads", "3")) == 3
    for bad in ("0", "two", "-1"):
        with pytest.raises(LoosefitInputError, match=rf"--threads.*at least 1.*'{bad}'"):
            threads_of(_parsed("--threads", bad))
