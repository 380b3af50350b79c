"""``loosefit diagnose``: where and why a clip's cloth goes deeper into the body than the
tolerance: a table of events, diagnosis.json and renders of the worst frames
(loosefit.eval.penetration)."""

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
    import torch

    from loosefit.api import tqdm_bar
    from loosefit.body.regions import body_parts
    from loosefit.data.format import write_json_atomic
    from loosefit.eval.penetration import diagnose_clip, format_events
    from loosefit.garment.quality import PENETRATION_TOLERANCE

    source = Path(args.source)
    tolerance = PENETRATION_TOLERANCE if args.tolerance is None else args.tolerance
    if not 0.0 < tolerance < 1.0 or args.top < 0 or args.merge_gap < 0:
        raise LoosefitInputError(
            "loosefit diagnose",
            "--tolerance, --top, --merge-gap",
            "0 < tolerance < 1 m, top >= 0, merge gap >= 0",
            f"{tolerance}, {args.top}, {args.merge_gap}",
        )
    seq, name, arms = _clip_and_arms(args, source)
    args.shape = ",".join(f"{k}={v}" for k, v in seq.avatar.get("shape", {}).items())
    avatar = build_avatar(args)
    avatar.check_motion(seq.motion)
    with torch.no_grad():
        body = avatar.pose_motion(seq.motion).vertices.float().cpu().numpy()  # (T, Vb, 3)
    parts = body_parts(avatar, arms)
    bar = tqdm_bar("diagnose", unit="frame")
    diag = diagnose_clip(
        seq.garment_vertices,
        body,
        seq.motion.rotations[:, 0],
        seq.fps,
        parts,
        tolerance=tolerance,
        merge_gap=args.merge_gap,
        progress=bar.progress,
    )
    bar.close()
    print(f"{name}: {diag.summary()}; arms collide: {arms}")
    print(format_events(diag.events, tolerance))
    out = Path(args.out or f"out/diagnose/{name}")
    out.mkdir(parents=True, exist_ok=True)
    frames = diag.worst_frames(args.top)
    faces = avatar.faces.cpu().numpy()
    renders = (
        _render_worst(args, diag, parts, seq, body, faces, name=name, out=out, frames=frames)
        if frames
        else []
    )
    report = {
        "clip": name,
        "source": str(source),
        "arm_collision": arms,
        **diag.to_json(),
        "renders": [str(p) for p in renders],
    }
    write_json_atomic(out / "diagnosis.json", report)
    log(f"wrote {out / 'diagnosis.json'}")
    return 0


def _clip_and_arms(args: argparse.Namespace, source: Path):
    """The clip ``SOURCE [CLIP]`` names, its name, and the arms its collider has (``--arms``;
    auto: the simulation's collider, the data set's, else the garment's)."""
    import json

    from loosefit.data.format import DatasetReader, read_any_sequence
    from loosefit.fitting.place import collider_arms
    from loosefit.inference.model_common import arm_collision_of

    if source.is_dir():
        if not args.clip:
            raise LoosefitInputError(
                source,
                "CLIP",
                "a clip of the data set after it",
                "none",
                hint="its clips: sequences/*.npz",
            )
        seq, name = DatasetReader(source, allow_incomplete=True).read(args.clip), args.clip
        manifest = source / "manifest.json"
    else:
        if args.clip:
            raise LoosefitInputError(source, "CLIP", "no clip after a sequence file", args.clip)
        seq, name = read_any_sequence(source), source.stem
        manifest = source.parent.parent / "manifest.json"  # a data set's sequences/NAME.npz
    arms = {"none": False, "upper": "upper", "all": True}.get(args.arms)
    if args.arms == "auto":
        config = json.loads(manifest.read_text()).get("config", {}) if manifest.is_file() else {}
        arms = arm_collision_of(config, collider_arms(seq.garment))
    return seq, name, arms


def _render_worst(
    args, diag, parts, seq, body, body_faces, *, name: str, out: Path, frames: list[int]
) -> list[Path]:
    """``diagnose``'s PNGs: each of ``frames`` whole and close up (loosefit.render.closeup)."""
    from PIL import Image

    from loosefit.eval.penetration import closeup
    from loosefit.render.closeup import render_penetration
    from loosefit.render.renderer import RenderConfig, Renderer

    pen, paths = diag.penetrations, []
    config = RenderConfig(width=args.size, height=args.size, labels=False, frame_counter=False)
    with Renderer(config) as renderer:
        for rank, t in enumerate(frames, 1):
            root = seq.motion.root_translation[t]
            view = closeup(pen, parts, t, seq.garment.num_vertices, root)
            title = (
                f"{name} frame {t} ({t / seq.fps:.2f} s): {int(view.deep.sum())} vertices "
                f"deeper than {1000 * pen.tolerance:.0f} mm, deepest "
                f"{100 * pen.max_depth[t]:.1f} cm, in the {view.regions[0]}"
            )
            image = render_penetration(
                body[t],
                body_faces,
                seq.garment_vertices[t],
                seq.garment.faces,
                view.deep,
                view.target,
                direction=view.direction,
                hidden=view.hidden,
                muted=~parts.colliding,
                size=args.size,
                title=title,
                hidden_label=", ".join(view.regions),
                renderer=renderer,
            )
            paths.append(out / f"worst{rank}_frame{t:05d}.png")
            Image.fromarray(image).save(paths[-1], optimize=True)
            log(f"wrote {paths[-1]}")
    return paths
