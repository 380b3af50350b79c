"""``loosefit diagnose``: its arguments, and the refusals before any work."""

from __future__ import annotations

from loosefit.cli import build_parser, main


def test_the_diagnosis_s_arguments():
    args = build_parser().parse_args(["diagnose", "ds", "clip_a"])
    assert (args.source, args.clip, args.top, args.arms, args.merge_gap) == (
        "ds",
        "clip_a",
        3,
        "auto",
        0,
    )


def test_bad_limits_are_refused_naming_them(toy_dataset, tmp_path, capsys):
    out = tmp_path / "d"
    seq = toy_dataset / "sequences" / "a.npz"
    assert main(["diagnose", str(seq), "--tolerance", "2", "--out", str(out)]) == 2
    assert "0 < tolerance < 1 m" in capsys.readouterr().err
    assert main(["diagnose", str(seq), "--top", "-1", "--out", str(out)]) == 2
    assert "top >= 0" in capsys.readouterr().err
    assert not out.exists()


def test_a_clip_after_a_sequence_file_or_none_after_a_data_set_is_refused(
    toy_dataset, tmp_path, capsys
):
    seq = toy_dataset / "sequences" / "a.npz"
    assert main(["diagnose", str(seq), "b", "--out", str(tmp_path / "d")]) == 2
    assert "no clip after a sequence file" in capsys.readouterr().err
    assert main(["diagnose", str(toy_dataset), "--out", str(tmp_path / "d")]) == 2
    assert "a clip of the data set after it" in capsys.readouterr().err
