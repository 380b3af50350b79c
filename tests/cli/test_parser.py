"""The ``loosefit`` parser: every command is there, with its help; the entry points."""

import subprocess
import sys

import pytest

from loosefit.cli import build_parser, main

COMMANDS = [
    "demo",
    "render",
    "simulate",
    "dataset",
    "dataset pack",
    "dataset unpack",
    "train",
    "train generative",
    "train motion",
    "train detail",
    "train baseline",
    "animate",
    "view",
    "export",
    "diagnose",
    "evaluate",
    "package",
    "export-model",
    "reconstruct",
    "interpolate",
    "motion",
    "inspect-motion",
    "inspect-character",
    "garment",
]


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_has_its_help(command, capsys):
    with pytest.raises(SystemExit) as exit_:
        main([*command.split(), "--help"])
    assert exit_.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith(f"usage: loosefit {command}")
    assert "issue" not in out.lower()  # what a flag does, not where it was asked for


def test_the_commands_are_listed_in_their_order():
    top = [c for c in COMMANDS if " " not in c]
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    assert list(sub.choices) == top


def test_each_command_runs_its_own_function():
    from loosefit.cli import animate, dataset, export, garment, generative, motion, simulate

    parse = build_parser().parse_args
    assert parse(["animate", "kick"]).func is animate.run
    assert parse(["dataset", "pack", "a", "b"]).func is dataset.run_pack
    assert parse(["dataset", "unpack", "a", "b"]).func is dataset.run_unpack
    assert parse(["export", "a.npz", "b.usd"]).func is export.run_export
    assert parse(["export-model", "a.onnx"]).func is export.run_export_model
    assert parse(["garment", "flared"]).func is garment.run
    assert parse(["interpolate", "--checkpoint", "c", "--a", "a:0", "--b", "b:1"]).func is (
        generative.run_interpolate
    )
    assert parse(["inspect-motion", "a.bvh"]).func is motion.run_inspect
    assert parse(["simulate"]).func is simulate.run


@pytest.mark.parametrize("module", ["loosefit", "loosefit.cli"])
def test_python_dash_m_runs_the_command(module):
    run = subprocess.run(
        [sys.executable, "-m", module, "train", "motion", "--help"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr
    assert run.stdout.startswith("usage: loosefit train motion")
