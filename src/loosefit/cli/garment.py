"""``loosefit garment``: make a skirt or a dress, or import (and ``--fit``) a garment file
onto the avatar."""

from __future__ import annotations

import argparse
from pathlib import Path

from loosefit.cli.common import (
    add_avatar_args,
    add_import_args,
    build_avatar,
    garment_template,
    log,
    offset,
)
from loosefit.errors import LoosefitInputError


def add_parser(sub) -> None:
    p = sub.add_parser(
        "garment",
        help="make a skirt or a dress, or import a garment file onto the avatar",
    )
    p.add_argument(
        "source",
        help="aline, flared, circle, dress, dress-strapless, or a garment "
        "file (.obj, .gltf, .glb) in any units and axes",
    )
    p.add_argument("--out", default="out/garment", help="output folder")
    p.add_argument("--resolution", default="cpu", choices=("cpu", "paper"))
    p.add_argument("--length", type=float, default=None, help="skirt or dress length, metres")
    add_import_args(p)
    p.add_argument(
        "--fit",
        action="store_true",
        help="a garment made for another body: push it out of the avatar (keeping "
        "its shape, Eq. 16) and drape it there, instead of refusing it; with "
        "--shape auto, first pick the anny body it fits best",
    )
    p.add_argument(
        "--settle",
        type=float,
        default=0.5,
        help="with --fit: seconds of drape on the avatar standing still",
    )
    add_avatar_args(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from loosefit.api.garment import save_garment

    is_file = Path(args.source).suffix.lower() in (".obj", ".gltf", ".glb")
    if args.fit and not is_file:
        raise LoosefitInputError(
            "--fit",
            "source",
            "a garment file (.obj, .gltf, .glb) made for another body",
            repr(args.source),
        )
    if is_file:
        placed = _from_file(args)
        template, avatar = placed.template, placed.avatar
        _log_import(placed.report)
    else:
        template = garment_template(args.source, build_avatar(args), args.resolution, args.length)
        if template is None:
            raise LoosefitInputError("loosefit garment", "source", "a style or a file", "'none'")
    if args.fit:
        fit = placed.fit
        for line in fit.format().splitlines():
            log(f"fitted: {line}")
        shape = ",".join(f"{k}={v:g}" for k, v in avatar.shape.items())
        tried = (
            f" ({fit.shape_tried} shapes tried): simulate it with --shape {shape}"
            if fit.shape_tried
            else ""
        )
        log(f"fitted to the avatar {shape}" + tried)
    out = Path(args.out)
    name = Path(args.source).stem
    save_garment(template, out, name)
    log(
        f"wrote {out / (name + '.obj')} and {out / (name + '.npz')}: {template.num_vertices} "
        f"vertices, {len(template.faces)} faces, {len(template.waist)} attached vertices "
        f"(metres, Z up, on the avatar's rest pose)"
    )
    if args.fit:
        preview = out / f"{name}.preview.png"
        if _fit_preview(preview, template, fit, avatar):
            log(f"wrote {preview}: the fitted garment on the avatar, front and side (check it)")
    return 0


def _log_import(report: dict) -> None:
    """What the import of a garment file guessed and did (``template.meta["import"]``)."""
    for key in ("units", "up", "kind"):
        r = report[key]
        how = "guessed" if r["guessed"] else "given"
        extra = (
            f" (it is then {r['height_m']:.2f} m high, {r['width_m']:.2f} m wide)"
            if key == "units" and r["guessed"]
            else ""
        )
        say = f"; say --{key} to change it" if r["guessed"] else ""
        log(f"{key}: {r['value']} ({how}){extra}" + say)
    shift = report["placement"]["translation_m"]
    log(
        f"placed: {report['placement']['rule']} (moved by "
        f"{', '.join(f'{100 * t:.1f}' for t in shift)} cm); held by "
        f"{report['attachment']['vertices']} vertices ({report['attachment']['as']}); "
        f"UVs: {report['uv_source']}"
    )


def _from_file(args: argparse.Namespace):
    """``garment FILE``: the file placed on the avatar of ``--shape``, or (``--fit``) fitted
    to it (``--shape auto``: to the anny body it fits best), as
    :func:`loosefit.api.garment.garment_from_file` returns it."""
    from loosefit.api.garment import fit_config, garment_from_file

    if not args.fit:
        avatar = build_avatar(args)
        return garment_from_file(
            args.source,
            avatar,
            units=args.units,
            up=args.up,
            kind=args.kind,
            offset=offset(args.offset),
            attach=args.attach,
        )
    auto = args.shape.strip() == "auto"
    if auto:
        log(
            "--shape auto: searching anny's weight, height and proportions for the body the "
            "garment fits best"
        )
    config, shift = fit_config(settle_seconds=args.settle), offset(args.offset)
    return garment_from_file(
        args.source,
        None if auto else build_avatar(args),
        fit=config,
        shape="auto" if auto else None,
        units=args.units,
        up=args.up,
        kind=args.kind,
        offset=shift,
        attach=args.attach,
        bars=True,
    )


def _fit_preview(path: Path, template, fit, avatar, size: int = 480) -> bool:
    """A front and side picture of a fitted garment on the avatar's rest pose
    (:func:`loosefit.api.garment.fit_preview`) written to ``path``; False (and why, logged)
    where nothing can render."""
    from loosefit.api.garment import fit_preview

    try:
        fit_preview(path, template, fit, avatar, size=size)
    except RuntimeError as exc:  # no OpenGL here: the garment is written all the same
        log(f"no preview picture: {exc}")
        return False
    return True
