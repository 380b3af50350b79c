"""The ``loosefit`` parser: each command's module adds its own subcommand, in this order."""

from __future__ import annotations

import argparse

from loosefit.cli import (
    animate,
    character,
    dataset,
    demo,
    diagnose,
    evaluate,
    export,
    garment,
    generative,
    motion,
    package,
    render,
    simulate,
    train,
    view,
)

# each adds one subcommand (its flags, and ``func``: the function that runs it)
COMMANDS = (
    demo.add_parser,
    render.add_parser,
    simulate.add_parser,
    dataset.add_parser,
    train.add_parser,
    animate.add_parser,
    view.add_parser,
    export.add_export_parser,
    diagnose.add_parser,
    evaluate.add_parser,
    package.add_parser,
    export.add_export_model_parser,
    generative.add_reconstruct_parser,
    generative.add_interpolate_parser,
    motion.add_motion_parser,
    motion.add_inspect_parser,
    character.add_inspect_parser,
    garment.add_parser,
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="loosefit",
        description="The ``loosefit`` command: thin wiring from arguments to one function each.",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    for add in COMMANDS:
        add(sub)
    return parser
