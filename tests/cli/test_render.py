"""``loosefit render``: one source of what to draw, and the render flags' defaults."""

from __future__ import annotations

import pytest

from loosefit.cli import build_parser


def test_one_source_is_required_and_only_one(capsys):
    p = build_parser()
    args = p.parse_args(["render", "--motion", "spin"])
    assert (args.motion, args.garment, args.out, args.views) == (
        "spin",
        "none",
        "out/render",
        "front,side",
    )
    assert (args.size, args.png_every, args.fixed_camera) == (480, 0, False)
    for argv in (["render"], ["render", "--motion", "spin", "--sequence", "a.npz"]):
        with pytest.raises(SystemExit) as exit_:
            p.parse_args(argv)
        assert exit_.value.code == 2
    assert "--motion" in capsys.readouterr().err
