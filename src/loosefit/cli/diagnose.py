"""``loosefit diagnose``: where and why a clip's cloth goes deeper into the body than the
tolerance: a table of events, diagnosis.json and renders of the worst frames
(loosefit.api.evaluate)."""

from __future__ import annotations

import argparse
from pathlib import Path

from loosefit.cli.common import build_avatar, log
from loosefit.errors import LoosefitInputError


def add_parser(sub) -> None:
    p = sub.add_parser("diagnose", help="where and why a clip's cloth goes deep inside the body")
    p.add_argument("source", help="a data set folder (then CLIP), or a sequence .npz")
    p.add_argument("clip", nargs="?", default=None, help="with a data set: the clip's name")
    p.add_argument("--out", default=None, help="folder (default out/diagnose/CLIP)")
    p.add_argument("--top", type=int, default=3, help="render this many worst frames")
    p.add_argument(
        "--tolerance",
        type=float,
        default=None,
        metavar="M",
        help="metres of depth that count (default 0.005, as simulate's)",
    )
    p.add_argument(
        "--merge-gap",
        type=int,
        default=0,
        help="frames without penetration that still join two events",
    )
    p.add_argument(
        "--arms",
        default="auto",
        choices=("auto", "none", "upper", "all"),
        help="the collider's arms (default: the data set's cloth config, else the garment's)",
    )
    p.add_argument("--size", type=int, default=360, help="pixels per rendered view")
    p.add_argument("--device", default="cpu", help="torch device for posing")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from loosefit.api import penetration_tolerance
    from loosefit.api.evaluate import diagnose_clip, open_clip

    tolerance = penetration_tolerance() if args.tolerance is None else args.tolerance
    if not 0.0 < tolerance < 1.0 or args.top < 0 or args.merge_gap < 0:
        raise LoosefitInputError(
            "loosefit diagnose",
            "--tolerance, --top, --merge-gap",
            "0 < tolerance < 1 m, top >= 0, merge gap >= 0",
            f"{tolerance}, {args.top}, {args.merge_gap}",
        )
    clip = open_clip(args.source, args.clip, arms=args.arms)
    args.shape = ",".join(f"{k}={v}" for k, v in clip.shape.items())
    avatar = build_avatar(args)
    bar = _LazyBar("diagnose", unit="frame")
    found = diagnose_clip(
        clip, avatar=avatar, tolerance=tolerance, merge_gap=args.merge_gap, progress=bar.progress
    )
    bar.close()
    print(found.summary())
    print(found.table())
    out = Path(args.out or f"out/diagnose/{clip.name}")
    renders = found.render_worst(
        out, top=args.top, size=args.size, written=lambda p: log(f"wrote {p}")
    )
    log(f"wrote {found.write_report(out, renders)}")
    return 0


class _LazyBar:
    """A progress bar shown from the first step of the work on (the body posed and its
    parts found before it)."""

    def __init__(self, desc: str, unit: str) -> None:
        self.desc, self.unit, self.bar = desc, unit, None

    def progress(self, done: int, total: int) -> None:
        from loosefit.api import tqdm_bar

        if self.bar is None:
            self.bar = tqdm_bar(self.desc, unit=self.unit)
        self.bar.progress(done, total)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
