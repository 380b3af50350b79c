"""The options a run shares through the API (loosefit.api.options): the stages left on,
the torch threads of a block and who chose them, an export's configuration."""

from __future__ import annotations

import pytest
import torch

from loosefit.api.options import export_config, most_threads, stages, torch_threads
from loosefit.errors import LoosefitInputError


def test_stages_are_the_runtime_s_switches():
    from loosefit.inference.stages import Stages

    assert stages() == Stages()
    off = stages(detail=False, lengths=False, collision=False, feedback=True)
    assert off == Stages(detail=False, lengths=False, collision=False, feedback=True)
    assert off.overlap  # a switch the API does not name keeps its default


def test_the_most_threads_are_the_default_policy_s_ceiling():
    from loosefit.inference.threads import MOST_THREADS

    assert most_threads() == MOST_THREADS == 4


def test_threads_hold_within_the_block_and_say_who_chose_them(monkeypatch):
    before = torch.get_num_threads()
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    monkeypatch.delenv("MKL_NUM_THREADS", raising=False)
    with torch_threads(1) as chosen:
        assert torch.get_num_threads() == 1
        assert (chosen.count, chosen.asked, chosen.variable) == (1, 1, None)
    assert torch.get_num_threads() == before
    with torch_threads() as chosen:
        assert chosen.asked is None and 1 <= chosen.count <= most_threads()
    monkeypatch.setenv("MKL_NUM_THREADS", "2")
    with torch_threads() as chosen:
        assert chosen.variable == "MKL_NUM_THREADS"
    with pytest.raises(LoosefitInputError, match=r"--threads.*at least 1"):
        with torch_threads(0, source="--threads"):
            pass


def test_an_export_s_configuration():
    from loosefit.export import ExportConfig

    assert export_config() == ExportConfig()
    config = export_config(up_axis="y", skinned_body=False)
    assert (config.up_axis, config.skinned_body) == ("Y", False)
    with pytest.raises(LoosefitInputError, match="up_axis"):
        export_config(up_axis="X")
