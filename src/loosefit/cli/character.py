"""``loosefit inspect-character``: anny's body fitted to a user's character, with the
misfit, and a sheet of the two side by side; and what ``loosefit animate CHARACTER.glb``
does with a character."""

from __future__ import annotations

import argparse
from pathlib import Path

from loosefit.cli.common import add_generative_arg, log


def add_inspect_parser(sub) -> None:
    p = sub.add_parser(
        "inspect-character",
        help="fit anny's body to a character (a skinned, animated .glb/.gltf): the "
        "phenotype found, how far the skins lie apart, and a sheet of the two",
    )
    p.add_argument("file", help="a .glb or .gltf with a skinned mesh and an animation")
    p.add_argument(
        "--checkpoint",
        default=None,
        help="the set whose body the fit starts from (default: the pretrained set)",
    )
    add_generative_arg(p)
    p.add_argument(
        "--sheet",
        metavar="PNG",
        default=None,
        help="write the character | the fitted anny | both, front and side, first frame",
    )
    p.set_defaults(func=run_inspect)


def run_inspect(args: argparse.Namespace) -> int:
    from loosefit.api import load
    from loosefit.api.character import character_sheet, fit_character

    animator = load(args.checkpoint)
    fitted = fit_character(args.file, animator=animator)
    c = fitted.character
    print(
        f"{args.file}: {c.num_vertices:,} vertices, {len(c.faces):,} triangles, skin of "
        f"{len(c.joint_names)} joints, {c.num_frames} frames at {animator.model.fps:g} fps"
    )
    print(f"fitted: {fitted.fit.describe()}")
    print(f"anny's hips follow '{fitted.hips}'")
    if args.sheet:
        out = character_sheet(fitted, args.sheet, animator=animator)
        log(f"wrote {out}")
    return 0


def animate_character(args: argparse.Namespace, animator, out: Path) -> int:
    """``animate CHARACTER.glb``: the garment on the character itself (``animator``: a
    :class:`loosefit.api.Animator`); writes the sequence on the fitted anny (``out``), the
    character's file with the garment beside it, and ``--export`` (their file with the
    garment, or the garment alone in their world)."""
    from loosefit.api import tqdm_bar
    from loosefit.cli.common import inference_threads, retarget_config

    log(f"{args.motion}: a character (a skinned mesh): fitting anny's body to it")
    frames = args.frames
    with inference_threads(args) as n:
        bar = tqdm_bar("rollout", unit="frame")
        dressed = animator.dress(
            args.motion, frames, bar.progress, threads=n, retarget=retarget_config(args)
        )
        bar.close()
    log(f"fitted: {dressed.fit.describe()}")
    inside = sum(r["inside_after"] > 0 for r in dressed.collisions)
    deepest = max(r["depth_after"] for r in dressed.collisions)
    log(
        f"collision handling against the character's mesh: {inside} of "
        f"{len(dressed.collisions)} frames keep cloth inside it (deepest {100 * deepest:.2f} cm)"
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    dressed.sequence(f"loosefit model {Path(args.checkpoint).resolve()}").save(out)
    glb = out.with_name(out.stem + "_dressed.glb")
    written = dressed.export(glb)
    if args.export:
        written += dressed.export(args.export)
    log(f"wrote {out} (on the fitted anny), " + ", ".join(map(str, written)))
    return 0
