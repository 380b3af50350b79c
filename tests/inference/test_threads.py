"""The default thread count for inference, its checks, and its scope."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from loosefit.errors import LoosefitInputError
from loosefit.inference.threads import (
    MOST_THREADS,
    check_threads,
    cpu_quota,
    default_threads,
    inference_threads,
    machine_cores,
)


@pytest.mark.parametrize(
    ("cores", "load", "current", "env", "expected"),
    [
        (2, 0.2, 2, {}, 2),  # idle: a thread a core
        (2, 1.2, 2, {}, 1),  # one other program running: one core left
        (2, 8.0, 2, {}, 1),  # busy: one, never none
        (2, -1.0, 2, {}, 2),  # a platform without a load average gives 0
        (16, 0.0, 16, {}, MOST_THREADS),  # idle and large: at most MOST_THREADS
        (16, 13.6, 16, {}, 2),  # 2.4 cores free
        (8, 0.0, 1, {}, 1),  # a smaller torch.set_num_threads of the user's stays
        (8, 7.0, 3, {"OMP_NUM_THREADS": "3"}, 3),  # the user's variable: torch's count kept
        (8, 0.0, 6, {"MKL_NUM_THREADS": "6"}, 6),  # torch reads this one too
        (2, 0.0, 2, {"OMP_NUM_THREADS": " "}, 2),  # set but empty: not a choice
        (4, 3.0, 4, {"OMP_NUM_THREADS": ""}, 1),
    ],
)
def test_the_default_is_the_free_cores_unless_the_user_chose(cores, load, current, env, expected):
    assert default_threads(cores, load, current, env) == expected


@pytest.mark.parametrize(
    ("text", "cores"),
    [
        ("200000 100000\n", 2),
        ("150000 100000", 2),  # 1.5 cores: rounded up
        ("50000 100000", 1),
        ("max 100000", None),  # no quota
        ("", None),
        ("lots of cpu", None),
    ],
)
def test_a_containers_quota_is_read_from_cpu_max(text, cores):
    assert cpu_quota(text) == cores


def test_the_machine_has_at_least_one_core_and_no_more_than_it_reports():
    import os

    assert 1 <= machine_cores() <= (os.cpu_count() or 1)


@pytest.mark.parametrize("bad", [0, -2, 1.5, "2", True, None])
def test_a_thread_count_is_a_whole_number_of_at_least_one(bad):
    with pytest.raises(
        LoosefitInputError, match="--threads: field 'threads': expected a whole number, at least 1"
    ):
        check_threads(bad, "--threads")


def test_numpy_integers_are_thread_counts():
    assert check_threads(np.int64(3)) == 3


def test_the_setting_is_scoped_to_the_block():
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        with inference_threads(1) as n:
            assert n == 1 and torch.get_num_threads() == 1
        assert torch.get_num_threads() == 2
        with pytest.raises(RuntimeError), inference_threads(1):
            raise RuntimeError("the count comes back after an error too")
        assert torch.get_num_threads() == 2
        with pytest.raises(LoosefitInputError), inference_threads(0):
            pass
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)


def test_the_default_reads_the_users_variable_and_torchs_count(monkeypatch):
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        monkeypatch.setenv("OMP_NUM_THREADS", "2")
        with inference_threads() as n:  # the user's variable: torch's count, whatever the load
            assert n == 2 == torch.get_num_threads()
        monkeypatch.delenv("OMP_NUM_THREADS")
        monkeypatch.delenv("MKL_NUM_THREADS", raising=False)
        torch.set_num_threads(1)
        with inference_threads() as n:  # never more than torch's own count
            assert n == 1
    finally:
        torch.set_num_threads(before)
