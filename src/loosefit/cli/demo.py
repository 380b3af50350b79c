"""``loosefit demo``: the main job, the pretrained model animating its skirt on a dance."""

from __future__ import annotations

import argparse
from pathlib import Path

from loosefit.cli.animate import physics_note, stage_line, throughput
from loosefit.cli.common import (
    add_avatar_args,
    add_bvh_args,
    add_render_args,
    add_runtime_args,
    add_threads_arg,
    build_avatar,
    garment_template,
    inference_threads,
    log,
    log_exported,
    render,
    retarget_config,
    threads_of,
)
from loosefit.cli.view import add_view_args, serve
from loosefit.errors import LoosefitInputError


def add_parser(sub) -> None:
    p = sub.add_parser(
        "demo",
        help="the main job: the pretrained model animates its skirt on "
        "a 20 s dance (video, USD, PC2); --physics simulates instead",
    )
    p.add_argument("--out", default="out/demo", help="output folder")
    p.add_argument(
        "--motion",
        default=None,
        help="procedural move, dance:SECONDS, or a file (default: dance:20; with --physics: spin)",
    )
    p.add_argument(
        "--max-frames",
        type=int,
        default=None,
        help="frames of the motion to use (default: all; with --physics: 90)",
    )
    p.add_argument("--start-frame", type=int, default=0, help="first frame of the motion to use")
    mode = p.add_mutually_exclusive_group()
    mode.add_argument(
        "--physics",
        action="store_true",
        help="simulate the skirt with Newton's VBD solver (minutes) instead",
    )
    mode.add_argument("--no-physics", action="store_true", help="carry the skirt rigidly instead")
    p.add_argument(
        "--checkpoint",
        default=None,
        help="a model to animate with (default: the pretrained set)",
    )
    add_runtime_args(p)
    add_threads_arg(p)
    p.add_argument("--sim-device", default="cpu", help="warp device for the simulation")
    p.add_argument(
        "--garment",
        default=None,
        help="--physics/--no-physics: skirt style (aline, flared, circle) or an OBJ "
        "(default flared)",
    )
    p.add_argument("--resolution", default="cpu", choices=("cpu", "paper"))
    p.add_argument("--seed", type=int, default=0, help="seeds the procedural dance")
    p.add_argument(
        "--realisation",
        type=int,
        default=None,
        metavar="N",
        help="the learned model: draw realisation N of the cloth (its residual process "
        "seeded by N, the same on every run); without it, the motion stage's garment",
    )
    p.add_argument("--fps", type=float, default=30.0)
    add_bvh_args(p)
    add_avatar_args(p)
    add_render_args(p)
    p.add_argument(
        "--view",
        action="store_true",
        help="then open the result in the browser viewer (as loosefit view)",
    )
    add_view_args(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """The main job: the pretrained model animating its skirt on a dance (``--physics``: the
    simulator instead; ``--no-physics``: the skirt carried rigidly)."""
    from loosefit.api import motion_for, tqdm_bar
    from loosefit.api.garment import carry_rigidly, dressed_sequence
    from loosefit.cli.common import open_model

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    learned = not (args.physics or args.no_physics)
    if learned and args.garment is not None:
        raise LoosefitInputError(
            "--garment",
            "garment",
            "no --garment: the pretrained model animates the skirt it was trained on (use "
            "--physics to simulate another)",
            repr(args.garment),
        )
    if args.realisation is not None and not learned:
        raise LoosefitInputError(
            "--realisation",
            "realisation",
            "no --realisation with --physics or --no-physics (the learned model draws it)",
            repr(args.realisation),
        )
    if threads_of(args) is not None and not learned:  # a bad count, or one nothing reads
        raise LoosefitInputError(
            "--threads",
            "threads",
            "no --threads with --physics or --no-physics (it sets the learned model's threads)",
            repr(args.threads),
        )
    spec = args.motion or ("dance:20" if learned else "spin")
    max_frames = args.max_frames if args.max_frames or learned else 90
    animator = None
    if learned:
        from loosefit.api import pretrained_checkpoint

        path = Path(args.checkpoint) if args.checkpoint else pretrained_checkpoint()
        animator = open_model(path)
        log(f"model {path.parent.name}: trained on {animator.trained_on}")
        physics_note(animator.model, animator.model.stages)
        avatar, template = animator.avatar(), animator.template
    else:
        avatar = build_avatar(args)
        template = garment_template(args.garment or "flared", avatar, args.resolution)
    motion = motion_for(
        spec,
        avatar,
        animator.fps if animator else args.fps,
        seed=args.seed,
        retarget=retarget_config(args),
        max_frames=max_frames,
        start_frame=args.start_frame,
    )
    log(f"motion '{motion.name}': {motion.num_frames} frames at {motion.fps:g} fps")
    body = avatar.pose_motion(motion)
    if animator is not None:
        with inference_threads(args) as n:
            bar = tqdm_bar("animate", unit="frame")
            seq = animator.animate(
                motion,
                progress=bar.progress,
                runtime=args.runtime,
                collision=args.collision,
                threads=n,
                realisation=args.realisation,
            )
            bar.close()
        garment, source = seq.vertices, f"loosefit model {path.parent.name}"
        log(realisation_line(animator.model, args.realisation))
        line = stage_line(animator.model, animator.model.stages, seq.rollout)
        log(throughput(motion, seq.rollout) + "; " + line)
    elif args.no_physics:
        garment = carry_rigidly(template, body, avatar)
        source = "rigid"
    else:
        garment, source = _simulate(args, avatar, template, motion), "newton-vbd"
    seq = dressed_sequence(motion, template, garment, avatar, source, body=body)
    seq.save(out / "sequence.npz")
    log(f"wrote {out / 'sequence.npz'} ({source})")
    if learned:  # the body posed above, once for both files and the viewer
        for suffix in (".usdc", ".pc2"):
            log_exported(seq.export(out / f"demo{suffix}"))
    title = f"loosefit demo: {motion.name}" + (" (learned)" if learned else f" ({source})")
    render(args, avatar, motion, template, garment, out, title=title, body=body)
    if args.view:
        serve([seq], [f"demo ({source})"], [str(out / "sequence.npz")], args)
    return 0


def _simulate(args: argparse.Namespace, avatar, template, motion):
    """``demo --physics``: the skirt simulated with Newton's VBD solver, (T, V, 3)."""
    from loosefit.api import tqdm_bar
    from loosefit.api.simulation import simulate_garment

    bar = tqdm_bar("simulate", unit="frame")
    result = simulate_garment(
        avatar, template, motion, device=args.sim_device, seed=args.seed, progress=bar.progress
    )
    bar.close()
    q = result.quality
    log(
        f"simulated at {result.seconds_per_frame:.2f} s/frame; garment inside the body: "
        f"{q['inside_max']:.4f} (worst frame), edge strain p99 {q['strain_p99']:.3f}"
    )
    return result.garment_vertices


def realisation_line(model, realisation: int | None) -> str:
    """What the learned garment is: the motion stage's, or a realisation of the cloth."""
    if realisation is not None:
        return (
            f"realisation {realisation} of the cloth (the set's residual process seeded by "
            f"{realisation}: the same garments on every run; another N, another way the cloth "
            "may land)"
        )
    if getattr(model, "residual", None) is not None:
        return (
            "the motion stage's garment, the centre of what the cloth may do; "
            "--realisation N draws one plausible realisation of it"
        )
    return "the motion stage's garment (this set has no residual process: no realisations)"
