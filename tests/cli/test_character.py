"""A user's own character: ``inspect-character``'s arguments, and ``animate`` of a character
refusing another body (its body is fitted)."""

from __future__ import annotations

from loosefit.cli import build_parser, main


def test_inspect_character_s_arguments():
    args = build_parser().parse_args(["inspect-character", "hero.glb", "--sheet", "s.png"])
    assert (args.file, args.checkpoint, args.sheet) == ("hero.glb", None, "s.png")


def test_a_character_on_another_body_is_refused(tmp_path, capsys, monkeypatch):
    import loosefit.api

    monkeypatch.setattr(loosefit.api, "is_character", lambda path: True)  # a skinned mesh
    out = tmp_path / "c"
    assert main(["animate", "hero.glb", "--shape", "height=0.8", "--out", str(out)]) == 2
    assert "none with a character (its body is fitted)" in capsys.readouterr().err
    assert not out.exists()
