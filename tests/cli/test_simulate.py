"""``loosefit simulate``: the data set it makes from the flags, and the seeds."""

from __future__ import annotations

import pytest

from loosefit.cli import build_parser
from loosefit.cli.simulate import dataset_config, parse_seeds
from loosefit.errors import LoosefitInputError


def test_seeds_are_distinct_whole_numbers():
    assert parse_seeds("0,1, 2") == [0, 1, 2]
    with pytest.raises(LoosefitInputError, match=r"--seeds.*'x' in '0,x'"):
        parse_seeds("0,x")
    with pytest.raises(LoosefitInputError):
        parse_seeds("1,1")  # the same seed twice


def test_the_flags_go_over_the_preset():
    p = build_parser()
    base = p.parse_args(["simulate"])
    config = dataset_config(base)
    args = p.parse_args(
        ["simulate", "--motions", "spin,kick", "--test", "kick", "--max-frames", "12"]
    )
    custom = dataset_config(args)
    assert custom.preset == "custom"
    assert custom.motions.specs == ("spin", "kick") and custom.motions.test == ("kick",)
    assert custom.motions.max_frames == 12
    assert config.preset != "custom"
