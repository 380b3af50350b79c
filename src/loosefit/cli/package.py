"""``loosefit package``: a trained model's stages in one folder, half precision, to share."""

from __future__ import annotations

import argparse

from loosefit.cli.common import add_generative_arg, log


def add_parser(sub) -> None:
    p = sub.add_parser(
        "package", help="a trained model's stages in one folder, half precision, to share"
    )
    p.add_argument("checkpoint", help="a motion run's model.pt or checkpoint.pt")
    add_generative_arg(p)
    p.add_argument("--detail", default=None, help="also this detail stage's model.pt")
    p.add_argument(
        "--out", required=True, help="folder for generative.pt, motion.pt (and detail.pt)"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from loosefit.api import package

    files = package(args.checkpoint, args.out, generative=args.generative, detail=args.detail)
    for f in files:
        log(f"wrote {f} ({f.stat().st_size / 1e6:.1f} MB)")
    return 0
