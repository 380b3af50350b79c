"""``loosefit dataset pack|unpack``: a data set small enough to share, and back."""

from __future__ import annotations

import argparse

from loosefit.cli.common import log

MIB = 2**20


def add_parser(sub) -> None:
    p = sub.add_parser("dataset", help="pack a data set small enough to share, or unpack one")
    actions = p.add_subparsers(dest="action", required=True)
    d = actions.add_parser(
        "pack",
        help="a data set folder into one file or numbered pieces "
        "(garment vertices to 0.02 mm, all else exact), with an index of "
        "sizes and sha256",
    )
    d.add_argument("folder", help="the data set folder (manifest.json, template.npz, sequences/)")
    d.add_argument("out", help="the pack's file (with --piece-mib: OUT.000, OUT.001, ...)")
    d.add_argument(
        "--piece-mib",
        type=float,
        default=None,
        metavar="N",
        help="cut the pack into pieces of at most N MiB",
    )
    d.add_argument("--workers", type=int, default=1, help="processes coding the clips")
    d.set_defaults(func=run_pack)
    d = actions.add_parser(
        "unpack", help="a pack into a data set folder, verified before it appears"
    )
    d.add_argument(
        "pack",
        help="the pack's file, a folder of its pieces, or their common "
        "prefix (e.g. ../shared/datasets/dance.lfz.)",
    )
    d.add_argument("dest", help="the data set folder to make (new or empty)")
    d.set_defaults(func=run_unpack)


def run_pack(args: argparse.Namespace) -> int:
    from loosefit.api import tqdm_bar
    from loosefit.api.data import pack_dataset

    bar = tqdm_bar(f"pack {args.folder}", "file")
    try:
        r = pack_dataset(
            args.folder,
            args.out,
            piece_mib=args.piece_mib,
            workers=args.workers,
            progress=bar.progress,
        )
    finally:
        bar.close()
    where = str(r.paths[0]) + (f" ... {r.paths[-1].name}" if len(r.paths) > 1 else "")
    print(
        f"{where}: {r.packed_bytes / MIB:.1f} MiB in {len(r.paths)} file(s), "
        f"{r.files} files ({r.clips} clips); {r.ratio:.1f}x smaller than the .npz files "
        f"({r.npz_bytes / MIB:.1f} MiB); vertices within {r.max_error * 1e3:.4f} mm of "
        f"the data set's (at most {r.step * 500:g} mm), every other array exact"
    )
    return 0


def run_unpack(args: argparse.Namespace) -> int:
    from loosefit.api import tqdm_bar
    from loosefit.api.data import unpack_dataset

    bar = tqdm_bar(f"unpack {args.pack}", "file")
    try:
        r = unpack_dataset(args.pack, args.dest, progress=bar.progress)
    finally:
        bar.close()
    checked = "the pack's index" if r.indexed else "its manifest"
    log(
        f"unpacked {r.files} files ({r.clips} clips) from {len(r.pieces)} file(s) into "
        f"{r.dest}, checked against {checked}"
    )
    return 0
