"""The ``loosefit`` command: thin wiring from arguments to one function each.

Each command is a module here holding its parser setup and the function that runs it;
:mod:`loosefit.cli.parser` lists them, :mod:`loosefit.cli.common` holds the flags several
share. Subcommands:

    demo            the pretrained model animates its skirt on a dance, written to a video
    render          a motion (BVH, saved or procedural) or a saved sequence to MP4 + PNG
    simulate        a garment data set simulated with Newton's VBD cloth solver
    dataset         pack a data set small enough to share, or unpack one (verified)
    train           train a learned stage: generative, motion, detail or baseline
    animate         a trained model animates its garment on a motion
    view            sequences in a 3D viewer in the browser (body, garment, colour by error)
    export          a sequence to USD, PC2 point caches or an OBJ sequence
    diagnose        where and why a clip's cloth goes deep inside the body
    evaluate        roll out held-out clips and compare them with the simulation
    package         a trained model's stages in one folder, half precision, to share
    export-model    the learned runtime as ONNX (+ JSON) for a game engine
    reconstruct     encode and decode a clip with a generative model
    interpolate     garments along a line between two latent codes
    motion          a BVH, glTF or SMPL file or a procedural move to a motion file (.npz)
    inspect-motion  a motion file's joints, how they map onto the avatar, height, units
    garment         make a parametric skirt or import a garment file, write OBJ + template
"""

from __future__ import annotations

import sys

from loosefit.cli.parser import build_parser
from loosefit.errors import LoosefitInputError

__all__ = ["build_parser", "main"]


def main(argv: list[str] | None = None) -> int:
    """Run ``loosefit ARGV``: a bad input is one ``loosefit: error:`` line and exit code 2."""
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except LoosefitInputError as exc:
        print(f"loosefit: error: {exc}", file=sys.stderr)
        return 2
