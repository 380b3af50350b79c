"""``loosefit evaluate``: the model through loosefit.load, the refusals before any rollout."""

from __future__ import annotations

import pytest

from loosefit.cli import build_parser, main
from tests.conftest import REPO

PAIR = REPO / "checkpoints" / "dance"


def test_the_evaluation_s_arguments():
    args = build_parser().parse_args(["evaluate", "--checkpoint", "m.pt", "--data", "ds"])
    assert (args.split, args.horizons, args.max_frames, args.rmse_only) == (
        "test",
        "100,500,1200",
        None,
        False,
    )
    with pytest.raises(SystemExit):
        build_parser().parse_args(["evaluate", "--data", "ds"])  # no checkpoint


def test_a_missing_checkpoint_is_refused(toy_dataset, tmp_path, capsys):
    argv = ["evaluate", "--checkpoint", str(tmp_path / "no.pt"), "--data", str(toy_dataset)]
    assert main([*argv, "--out", str(tmp_path / "e")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_members_need_a_data_set_and_horizons_numbers(toy_dataset, tmp_path, capsys):
    seq = str(toy_dataset / "sequences" / "a.npz")
    base = ["evaluate", "--checkpoint", str(PAIR / "motion.pt"), "--out", str(tmp_path / "e")]
    assert main([*base, "--data", seq, "--members", str(toy_dataset)]) == 2
    assert "a data set folder to gather members with" in capsys.readouterr().err
    assert main([*base, "--data", seq, "--horizons", "10,lots"]) == 2
    assert "comma-separated frame counts" in capsys.readouterr().err
    assert not (tmp_path / "e").exists()
