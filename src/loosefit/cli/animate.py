"""``loosefit animate``: a trained model animates its garment on a motion; and the lines it
(and ``demo``) logs about the model and the rollout."""

from __future__ import annotations

import argparse
import re
import time
from pathlib import Path

from loosefit.cli.common import (
    add_bvh_args,
    add_export_format_args,
    add_generative_arg,
    add_render_args,
    add_runtime_args,
    add_stage_args,
    add_threads_arg,
    export_config,
    inference_threads,
    log,
    log_exported,
    render,
    retarget_config,
    stages,
    threads_of,
)
from loosefit.errors import LoosefitInputError


def add_parser(sub) -> None:
    p = sub.add_parser("animate", help="animate the garment on a motion with a trained model")
    p.add_argument(
        "inputs",
        nargs="+",
        metavar="[CHECKPOINT] MOTION",
        help="a motion run's model.pt or checkpoint.pt (default: the pretrained set in "
        "checkpoints/dance), then a .bvh, .gltf/.glb or .npz (loosefit or SMPL) motion, a "
        "procedural move, or dance:SECONDS "
        "(mirror:MOTION mirrors one left-right; speed:F:, pitch:DEGREES: and spin:TURNS: "
        "change it: docs/use/INPUTS.md; A+B plays one after another). A .glb/.gltf "
        "with a skinned mesh is a character: the garment goes on its own mesh, and "
        "NAME_dressed.glb (their file with the garment) is written beside the sequence",
    )
    add_generative_arg(p)
    p.add_argument(
        "--shape",
        default="",
        help="another body, as anny phenotypes in [0, 1]: e.g. 'height=0.8,weight=0.3' "
        "(gender, age, muscle, weight, height, proportions; those not named as the trained "
        "body's). The garment is sized to that body and animated on it",
    )
    p.add_argument(
        "--frames",
        type=int,
        default=None,
        help="frames to animate (longer than the motion: it plays again)",
    )
    p.add_argument("--start-frame", type=int, default=0)
    p.add_argument(
        "--out",
        default="out/animate",
        help="the sequence .npz to write, or a folder for MOTION.npz",
    )
    p.add_argument("--render", action="store_true", help="also render a video and PNGs")
    p.add_argument(
        "--on-anny",
        action="store_true",
        help="a character's file: read only its animation, and animate on anny",
    )
    p.add_argument("--seed", type=int, default=0, help="seeds a procedural move")
    p.add_argument(
        "--realisation",
        type=int,
        default=None,
        metavar="N",
        help="draw realisation N of the cloth: the set's residual process seeded by N, the "
        "same garments on every run and machine (without it: the motion stage's garment, "
        "the centre of what the cloth may do)",
    )
    p.add_argument(
        "--export",
        default=None,
        metavar="PATH",
        help="also export garment and body: .usd/.usdc/.usda (USD), .abc (Alembic), .glb "
        "(glTF), .pc2 (point caches + OBJ), or a folder (OBJ per frame)",
    )
    add_export_format_args(p)
    add_bvh_args(p)
    add_stage_args(p)
    add_runtime_args(p)
    add_threads_arg(p)
    add_render_args(p, views="front,side")
    p.set_defaults(func=run)


def _checkpoint_and_motion(args: argparse.Namespace) -> bool:
    """``animate [CHECKPOINT] MOTION``: without a checkpoint, the pretrained default (then
    True)."""
    if len(args.inputs) not in (1, 2):
        raise LoosefitInputError(
            "animate",
            "arguments",
            "[CHECKPOINT] MOTION",
            f"{len(args.inputs)} arguments: {args.inputs}",
        )
    if len(args.inputs) == 2:
        args.checkpoint, args.motion = args.inputs
        return False
    from loosefit.api import pretrained_checkpoint

    args.checkpoint, args.motion = pretrained_checkpoint(), args.inputs[0]
    if not args.checkpoint.is_file():
        raise LoosefitInputError(
            args.checkpoint,
            "checkpoint",
            "the pretrained pair of a loosefit clone",
            "no such file",
            hint="pass a checkpoint: loosefit animate CHECKPOINT MOTION",
        )
    log(f"no checkpoint given: the pretrained default {args.checkpoint}")
    return True


def run(args: argparse.Namespace) -> int:
    from loosefit.api import check_export_path, is_character, motion_for, tqdm_bar
    from loosefit.cli.common import open_model, parse_shape

    threads_of(args)  # a bad count before the work
    shape = parse_shape(args.shape)  # and a malformed body
    pretrained = _checkpoint_and_motion(args)
    animator = open_model(args.checkpoint, args.generative, args.detail)
    if pretrained:  # what it was trained on, from the record it loaded with
        log(f"model {Path(args.checkpoint).parent.name}: trained on {animator.trained_on}")
    on = stages(args)
    physics_note(animator.model, on)
    if not args.on_anny and is_character(args.motion):
        from loosefit.cli.character import animate_character

        if shape:
            raise LoosefitInputError(
                "--shape", "shape", "none with a character (its body is fitted)", args.shape
            )
        if args.realisation is not None:
            raise LoosefitInputError(
                "--realisation", "realisation", "none with a character", args.realisation
            )
        out = Path(args.out)
        name = re.sub(r"[^A-Za-z0-9_.-]+", "_", Path(args.motion).stem) or "character"
        path = out if out.suffix == ".npz" else out / f"{name}.npz"
        return animate_character(args, animator, path)
    avatar = other_body(animator, shape)
    if args.frames is not None and args.frames < 1:
        raise LoosefitInputError("--frames", "frames", "at least 1", args.frames)
    motion = motion_for(
        args.motion,
        avatar,
        animator.fps,
        args.frames,
        args.start_frame,
        args.seed,
        retarget=retarget_config(args),
    )
    # the motion's own name (a chain's names all of its parts), safe as a file name
    name = re.sub(r"[^A-Za-z0-9_.-]+", "_", motion.name).strip("._") or "motion"
    out = Path(args.out)
    if out.suffix not in ("", ".npz") and not out.is_dir():
        raise LoosefitInputError("--out", "out", "a .npz file or a folder", str(out))
    path = out if out.suffix == ".npz" else out / f"{name}.npz"
    if args.export:
        check_export_path(args.export)  # before the work, not after
    log(f"animating {motion.num_frames} frames of '{motion.name}'")
    with inference_threads(args) as n:
        bar = tqdm_bar("rollout", unit="frame")
        seq = animator.animate(
            motion,
            stages=on,
            progress=bar.progress,
            runtime=args.runtime,
            collision=args.collision,
            threads=n,
            shape=shape,
            realisation=args.realisation,
        )
        bar.close()
    result = seq.rollout
    log(stage_line(animator.model, on, result))
    seq.source = f"loosefit model {Path(args.checkpoint).resolve()}"
    path.parent.mkdir(parents=True, exist_ok=True)
    seq.save(path)
    log(f"{throughput(motion, result)}; wrote {path}")
    if args.export:
        log_exported(seq.export(args.export, config=export_config(args)))
    if args.render:
        out = path.with_name(path.stem + "_render")
        title = f"{motion.name} (loosefit rollout)"
        render(args, avatar, motion, seq.template, seq.vertices, out, title=title)
    return 0


def other_body(animator, shape: dict):
    """The avatar a motion is animated on: ``--shape``'s body, prepared (and logged), or
    the trained body's."""
    if not shape:
        return animator.avatar()
    if not hasattr(animator.model, "other_body"):
        raise LoosefitInputError(
            "--shape",
            "shape",
            "our model (a baseline animates on the body it was trained on)",
            type(animator.model).__name__,
        )
    t = time.perf_counter()
    body = animator.model.other_body(shape)
    changed = ", ".join(f"{k}={v:g}" for k, v in body.shape.items() if k in shape)
    log(f"body {changed}: prepared in {time.perf_counter() - t:.1f} s (the garment sized to it)")
    return body.avatar


def physics_note(model, stages) -> None:
    """Say which physics loss terms (membrane, bending, ...: the garment's edge lengths and
    angles held to rest) a model's stages were trained without."""
    missing = getattr(model, "missing_physics_terms", ())
    if missing:
        fix = (
            "the edge-length stage restores them"
            if stages.lengths
            else "--no-lengths leaves them so"
        )
        log(
            f"this model was trained without the physics terms {', '.join(missing)}: "
            f"its decoders give edges shorter than rest; {fix}"
        )


def throughput(motion, result) -> str:
    """How long a rollout took, apart from the clip's own frame rate: "animated 274 frames
    of a 30 fps clip (9.1 s) in 55.0 s (5 frames per second)"."""
    extra = result.frames - motion.num_frames
    preroll = f", {extra} frames of preroll more" if extra > 0 else ""
    return (
        f"animated {motion.num_frames} frames of a {motion.fps:g} fps clip "
        f"({motion.num_frames / motion.fps:.1f} s) in {result.seconds:.1f} s "
        f"({result.frames_per_second:.0f} frames per second{preroll})"
    )


def stage_line(model, stages, result) -> str:
    """What ran after the decoders, and what collision handling did."""
    from loosefit.api import penetration_tolerance

    tolerance = penetration_tolerance()
    ran = ["motion"]
    if stages.detail and model.detail is not None:
        ran.append("detail")
    elif stages.detail:
        ran.append("(no detail stage in this checkpoint)")
    if hasattr(model, "restorer") and model.restorer(stages) is not None:  # ours
        ran.append("edge lengths")
    if stages.collision:
        ran.append("collision")
    line = "stages: " + " -> ".join(ran)
    if result.collisions:
        before = sum(c["inside_before"] > 0 for c in result.collisions)
        after = [c for c in result.collisions if c["inside_after"] > 0]
        deep = sum(c["depth_after"] > tolerance for c in result.collisions)
        whole = model.collision.whole_body or model.arm_collision is True
        body = "the body (arms and hands included)" if whole else "the body (without its arms)"
        line += (
            f"; collision handling: {before} of {len(result.collisions)} frames had cloth "
            f"inside {body}, {len(after)} still do, {deep} deeper than "
            f"{tolerance * 1000:.0f} mm"
        )
        if after:
            worst = max(
                range(len(result.collisions)), key=lambda k: result.collisions[k]["depth_after"]
            )
            depth = result.collisions[worst]["depth_after"]
            line += f" (deepest: frame {worst}, {100 * depth:.2f} cm)"
    return line
