"""``loosefit export`` (a sequence to USD, PC2, OBJ) and ``export-model`` (ONNX): the
arguments, and the refusals before any work."""

from __future__ import annotations

from loosefit.cli import build_parser, main


def test_export_model_s_arguments_and_defaults():
    args = build_parser().parse_args(["export-model", "out.onnx"])
    assert (args.checkpoint, args.opset, args.no_detail, args.no_check) == (None, 17, False, False)


def test_only_a_sequence_file_is_exported(tmp_path, capsys):
    other = tmp_path / "motion.bvh"
    other.write_text("HIERARCHY")
    assert main(["export", str(other), str(tmp_path / "out.usdc")]) == 2
    assert "a sequence .npz" in capsys.readouterr().err
    assert not (tmp_path / "out.usdc").exists()


def test_export_model_of_a_missing_checkpoint_is_refused(tmp_path, capsys):
    argv = ["export-model", str(tmp_path / "m.onnx"), "--checkpoint", str(tmp_path / "no.pt")]
    assert main(argv) == 2
    assert "no such file" in capsys.readouterr().err
