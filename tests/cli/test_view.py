"""``loosefit view``: the sequences and the viewer's flags (``demo --view`` shares them)."""

from __future__ import annotations

from loosefit.cli import build_parser


def test_the_viewer_s_arguments_and_defaults():
    args = build_parser().parse_args(["view", "a.npz", "b.npz"])
    assert args.sequences == ["a.npz", "b.npz"] and args.data is None and args.clip is None
    assert (args.port, args.host, args.colour, args.paused) == (8080, "127.0.0.1", "plain", False)
    args = build_parser().parse_args(["view", "--data", "ds", "--clip", "c", "--port", "9000"])
    assert (args.sequences, args.data, args.clip, args.port) == ([], "ds", "c", 9000)


def test_demo_takes_the_same_viewer_flags():
    args = build_parser().parse_args(["demo", "--view", "--port", "8123", "--colour", "strain"])
    assert (args.view, args.port, args.colour) == (True, 8123, "strain")
