"""``loosefit export`` (a sequence to USD, PC2, OBJ) and ``export-model`` (ONNX): the
arguments, and the refusals before any work."""

from __future__ import annotations

import pytest

from loosefit.cli import build_parser, main
from loosefit.cli.export import engine_checkpoint
from loosefit.errors import LoosefitInputError
from tests.conftest import REPO

PAIR = REPO / "checkpoints" / "dance"


def test_export_model_s_arguments_and_defaults():
    args = build_parser().parse_args(["export-model", "out.onnx"])
    assert (args.checkpoint, args.opset, args.no_detail, args.no_check) == (None, 17, False, False)


def test_only_a_sequence_file_is_exported(tmp_path, capsys):
    other = tmp_path / "motion.bvh"
    other.write_text("HIERARCHY")
    assert main(["export", str(other), str(tmp_path / "out.usdc")]) == 2
    assert "a sequence .npz" in capsys.readouterr().err
    assert not (tmp_path / "out.usdc").exists()


def test_the_engine_tier_is_the_file_itself_or_the_one_beside(tmp_path):
    assert engine_checkpoint(PAIR / "engine.pt") == PAIR / "engine.pt"
    assert engine_checkpoint(PAIR / "motion.pt") == PAIR / "engine.pt"
    lonely = tmp_path / "motion.pt"
    lonely.write_bytes(b"")
    with pytest.raises(LoosefitInputError, match="train one: loosefit train engine"):
        engine_checkpoint(lonely)


def test_export_model_of_a_missing_checkpoint_is_refused(tmp_path, capsys):
    argv = ["export-model", str(tmp_path / "m.onnx"), "--checkpoint", str(tmp_path / "no.pt")]
    assert main(argv) == 2
    assert "no such file" in capsys.readouterr().err
