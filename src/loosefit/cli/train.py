"""``loosefit train generative|motion|detail|baseline|engine|residual``: train a learned stage
(resumable), or fit a motion stage's residual process.

Each stage is its own subcommand with only its own flags: ``add_common_args`` adds the
ones every stage takes, the ``_add_*_args`` helpers the ones a few share. A flag of
another stage is refused by name (``train motion --no-discriminator`` says that flag
belongs to ``train detail``): ``_refuse_other_stages_flags`` gives every stage's parser a
hidden entry for each flag the other stages have.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
from pathlib import Path

from loosefit.cli.common import log
from loosefit.errors import LoosefitInputError

STAGES = ("generative", "motion", "detail", "baseline", "engine", "residual")


def add_parser(sub) -> None:
    p = sub.add_parser(
        "train",
        help="train a learned stage (resumable)",
        description="Train a learned stage (resumable): loosefit train STAGE [flags]; "
        "each stage's flags: loosefit train STAGE --help.",
    )
    stages = p.add_subparsers(dest="stage", required=True, metavar="STAGE")
    parsers = {
        "generative": _add_generative_parser(stages),
        "motion": _add_motion_parser(stages),
        "detail": _add_detail_parser(stages),
        "baseline": _add_baseline_parser(stages),
        "engine": _add_engine_parser(stages),
        "residual": _add_residual_parser(stages),
    }
    _refuse_other_stages_flags(p, parsers)


# --- the flags ----------------------------------------------------------------------------


def add_common_args(p: argparse.ArgumentParser, out: str) -> None:
    """The flags every stage takes; ``out``: the default run folder, as help text."""
    p.add_argument("--data", default="datasets/demo", help="a dataset folder")
    p.add_argument("--preset", default="cpu", help="cpu (about 20 CPU minutes) or full (GPU)")
    p.add_argument("--out", default=None, help=f"run folder (default {out})")
    p.add_argument("--epochs", type=int, default=None)
    p.add_argument("--batch-size", type=int, default=None)
    p.add_argument("--lr", type=float, default=None)
    p.add_argument("--max-frames", type=int, default=None, help="frames per clip")
    p.add_argument("--device", default="cpu", help="torch device")
    p.add_argument("--seed", type=int, default=None, help="training seed (default 0)")
    p.add_argument("--threads", type=int, default=0, help="torch CPU threads (0: default)")


def _common_overrides(args: argparse.Namespace) -> dict:
    """The preset overrides of :func:`add_common_args`'s flags (None: the preset's)."""
    return {
        "epochs": args.epochs,
        "device": args.device,
        "max_frames": args.max_frames,
        "batch_size": args.batch_size,
        "lr": args.lr,
        "seed": args.seed,
    }


def _add_precision_arg(p: argparse.ArgumentParser) -> None:
    """``--precision`` (generative, motion; detail and baseline train in fp32)."""
    p.add_argument(
        "--precision",
        default=None,
        choices=("fp32", "bf16"),
        help="the networks' forward pass in fp32 (default) or bf16 "
        "(autocast; losses and optimiser stay fp32)",
    )


def _add_physics_args(p: argparse.ArgumentParser, *extra: str) -> None:
    """The weights of the physics loss terms (generative, motion): ``--membrane``,
    ``--bending``, and ``extra`` of ``collision`` (both) and ``flare`` and ``speed``
    (motion)."""
    terms = {
        "membrane": "membrane term (edge lengths against rest",
        "bending": "bending term (dihedral angles against rest",
        "collision": "collision term (cloth outside the whole body",
        "flare": "hem-flare term (the hem's mean distance from the root's vertical axis "
        "against the simulation's",
        "speed": "speed term (each vertex's speed against the simulation's, whatever its direction",
    }
    for name in ("membrane", "bending", *extra):
        p.add_argument(
            f"--{name}",
            type=float,
            default=None,
            metavar="W",
            help=f"weight of the {terms[name]}; default 0)",
        )


def _add_init_arg(p: argparse.ArgumentParser) -> None:
    """``--init`` (generative, motion, detail: a baseline trains from scratch)."""
    p.add_argument(
        "--init",
        default=None,
        metavar="CHECKPOINT",
        help="start from this checkpoint's weights (a run's or a packaged set's, same "
        "garment and configuration): fine-tuning",
    )


def _add_clip_args(p: argparse.ArgumentParser, joints: bool = True) -> None:
    """What the network trains on: ``--mirror`` and (motion, baseline) ``--joints``."""
    p.add_argument(
        "--mirror",
        action="store_true",
        help="also train on every clip mirrored left-right (twice the data, no "
        "simulation; the garment must be mirror-symmetric)",
    )
    if not joints:
        return
    p.add_argument(
        "--joints",
        default=None,
        choices=("all", "lower"),
        help="the joints whose rotations the network sees: all (default) or lower "
        "(spine and legs, what moves the skin a skirt touches)",
    )


def _add_generative_parser(stages) -> argparse.ArgumentParser:
    p = stages.add_parser(
        "generative",
        help="the garment VAE (3.2)",
        description="Train the generative model, the garment VAE (paper 3.2).",
    )
    p.add_argument(
        "--decoder",
        default="decomposed",
        help="decomposed (the paper's), vertex or ssdr (its ablations), or basis (a linear "
        "basis of the training garments and a UV offset map: held-out motion decoded closer)",
    )
    p.add_argument("--basis-size", type=int, metavar="K", help="decoder basis: K directions (128)")
    add_common_args(p, "runs/generative-PRESET-DECODER")
    _add_precision_arg(p)
    _add_physics_args(p, "collision")
    p.add_argument(
        "--kl",
        type=float,
        default=None,
        metavar="W",
        help="weight of the latent's KL term (lambda_3; default 1e-3): lower lets the "
        "decoder reconstruct closer, at the cost of a less regular latent",
    )
    _add_clip_args(p, joints=False)
    _add_init_arg(p)
    p.set_defaults(func=run_generative)
    return p


def _add_motion_parser(stages) -> argparse.ArgumentParser:
    p = stages.add_parser(
        "motion",
        help="the motion encoder (3.3)",
        description="Train the motion encoder (paper 3.3) on a trained generative model.",
    )
    p.add_argument("--generative", default=None, help="the generative checkpoint")
    p.add_argument(
        "--no-previous-state",
        action="store_true",
        help="the 'w/o ps' ablation (no previous garment input)",
    )
    p.add_argument(
        "--previous",
        default=None,
        choices=("scheduled", "teacher"),
        help="previous states by scheduled sampling (default) or ground truth",
    )
    p.add_argument(
        "--unroll",
        action="store_true",
        help="differentiate through the encoder's own fed-back predictions within a "
        "window (unrolled training, as for learned simulators)",
    )
    _add_clip_args(p)
    add_common_args(p, "runs/motion-PRESET-ps, or -nops")
    _add_precision_arg(p)
    _add_physics_args(p, "collision", "flare", "speed")
    _add_init_arg(p)
    p.set_defaults(func=run_motion)
    return p


def _add_detail_parser(stages) -> argparse.ArgumentParser:
    p = stages.add_parser(
        "detail",
        help="the detail enhancement module (3.4) on a trained motion stage's rollouts",
        description="Train the detail enhancement module (paper 3.4) on a trained motion "
        "stage's rollouts.",
    )
    p.add_argument("--motion", default=None, help="the motion stage's model.pt")
    p.add_argument(
        "--generative",
        default=None,
        help="the generative checkpoint (default: the one the motion stage records)",
    )
    p.add_argument(
        "--no-discriminator",
        action="store_true",
        help="the ablation without the multi-scale discriminator (Table 2's middle row)",
    )
    p.add_argument(
        "--edge-weight",
        type=float,
        default=None,
        help="weight of an L1 edge-length term added to Eq. 13 (default 0, the paper's)",
    )
    add_common_args(p, "runs/detail-PRESET-full, -nodisc, -full-edge or -nodisc-edge")
    _add_init_arg(p)
    p.set_defaults(func=run_detail)
    return p


def _add_baseline_parser(stages) -> argparse.ArgumentParser:
    p = stages.add_parser(
        "baseline",
        help="one of the paper's baselines (--method)",
        description="Train one of the paper's baselines (--method).",
    )
    p.add_argument(
        "--method",
        default=None,
        choices=("santesteban", "virtual-bones"),
        help="Santesteban et al. 2019 (skinned to the body, GRU displacements, "
        "push-out) or Pan et al. 2022 (virtual bones from a skinning decomposition)",
    )
    p.add_argument("--bones", type=int, default=None, help="virtual-bones: bones")
    _add_clip_args(p)
    add_common_args(p, "runs/baseline-PRESET-METHOD")
    p.set_defaults(func=run_baseline)
    return p


def _add_engine_parser(stages) -> argparse.ArgumentParser:
    p = stages.add_parser(
        "engine",
        help="the engine tier: the motion stage's dynamics on a linear garment basis, for a "
        "game engine (docs/use/ENGINE_EXPORT.md)",
        description="Train the engine tier of a full model: its dynamics (motion features, "
        "a recurrent state, the previous garment) mapped to the coefficients of a PCA basis "
        "of the data set's garments, decoded by one matrix product.",
    )
    p.add_argument(
        "--motion",
        default=None,
        help="the full model's motion-stage checkpoint, whose settled drape the tier starts "
        "from (default: the pretrained set's)",
    )
    p.add_argument("--basis", type=int, default=None, help="basis size K (default 64)")
    p.add_argument(
        "--targets",
        default=None,
        choices=("simulation", "rollout"),
        help="learn the simulated garments (default) or the full model's rollouts (distilled)",
    )
    p.add_argument("--no-mirror", action="store_true", help="leave out the mirrored clips")
    p.add_argument(
        "--membrane-weight",
        type=float,
        default=None,
        metavar="W",
        help="weight of the membrane term (mean squared edge strain of the decoded garment); "
        "default 0",
    )
    p.add_argument(
        "--procedural",
        type=int,
        default=None,
        metavar="N",
        help="add N procedural dances (the demo's moves) to the training clips, distilled "
        "from the full model's rollouts of them; default 0",
    )
    p.add_argument(
        "--noise",
        type=int,
        default=None,
        metavar="N",
        help="a stochastic tier: N noise numbers a frame, drawn from a seed (each seed one "
        "plausible realisation of the cloth), trained with the energy score against the "
        "simulation; default 0 (deterministic)",
    )
    p.add_argument(
        "--noise-correlation",
        type=float,
        default=None,
        metavar="RHO",
        help="a stochastic tier's noise correlated from frame to frame (an AR(1) process, "
        "RHO in [0, 1); 0.95 at 30 fps holds a draw for about 20 frames); default 0 (white)",
    )
    p.add_argument(
        "--samples",
        type=int,
        default=None,
        metavar="S",
        help="a stochastic tier's realisations of each clip scored together in training "
        "(default 2)",
    )
    add_common_args(p, "runs/engine-PRESET")
    p.set_defaults(func=run_engine)
    return p


def _add_residual_parser(stages) -> argparse.ArgumentParser:
    p = stages.add_parser(
        "residual",
        help="a motion stage's residual process: seeded realisations of the cloth "
        "(`loosefit animate --realisation N`)",
        description="Fit a motion stage's residual process: its rollouts through the data "
        "set's training clips against the simulation, the leading directions of what it "
        "misses, drawn in time as an AR(1) process. Seconds a clip; no gradient, the "
        "motion stage is not changed. Writes residual.pt beside the motion stage.",
    )
    p.add_argument("--data", default="datasets/demo", help="the data set it was trained on")
    p.add_argument(
        "--motion",
        default=None,
        help="the motion stage's checkpoint (default: the pretrained set's motion.pt)",
    )
    p.add_argument("--directions", type=int, default=8, help="directions kept (default 8)")
    p.add_argument(
        "--correlation",
        type=float,
        default=0.97,
        metavar="RHO",
        help="the AR(1) correlation from frame to frame, in [0, 1) (default 0.97)",
    )
    p.add_argument(
        "--scale",
        type=float,
        default=1.0,
        help="times the training residuals' spread (default 1; the pretrained set's scale "
        "is chosen on validation clips by bench/quality/residual_process.py)",
    )
    p.add_argument(
        "--no-gain",
        action="store_true",
        help="the same spread every frame (default: following the motion's intensity, "
        "fitted on the data set's validation clips where it has any)",
    )
    p.add_argument("--out", default=None, help="the file (default residual.pt beside --motion)")
    p.add_argument("--threads", type=int, default=0, help="torch CPU threads (0: default)")
    p.set_defaults(func=run_residual)
    return p


class _OtherStagesFlag(argparse.Action):
    """A hidden entry for a flag this parser lacks: refused, naming where it belongs.

    On a stage's parser, ``owners`` are the stages that take the flag; on ``train``'s own
    parser (a flag before the stage), every stage that takes it, and the error asks for
    the stage first."""

    def __init__(self, option_strings, dest, owners=(), stage=None, **kwargs):
        super().__init__(
            option_strings,
            dest=argparse.SUPPRESS,
            nargs="?",
            default=argparse.SUPPRESS,
            help=argparse.SUPPRESS,
        )
        self.owners, self.stage = owners, stage

    def __call__(self, parser, namespace, values, option_string=None):
        names = [f"`loosefit train {s}`" for s in self.owners]
        where = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
        if self.stage is None:
            parser.error(
                f"{option_string} belongs to {where}: name the stage first, "
                f"`loosefit train STAGE {option_string} ...` (STAGE: {', '.join(STAGES)})"
            )
        parser.error(
            f"{option_string} belongs to {where}, not to `loosefit train {self.stage}` "
            f"(its flags: `loosefit train {self.stage} --help`)"
        )


def _refuse_other_stages_flags(train: argparse.ArgumentParser, parsers: dict) -> None:
    """Every flag of a stage, on the other stages' parsers and on ``train``'s own (a flag
    given before the stage), as an error that names the stages it belongs to."""
    flags = {stage: _flags(p) for stage, p in parsers.items()}
    owners: dict[str, list[str]] = {}
    for stage, names in flags.items():
        for name in names:
            owners.setdefault(name, []).append(stage)
    for stage, p in parsers.items():
        for name in sorted(set(owners) - flags[stage]):
            p.add_argument(name, action=_OtherStagesFlag, owners=owners[name], stage=stage)
    for name in sorted(set(owners) - _flags(train)):
        train.add_argument(name, action=_OtherStagesFlag, owners=owners[name])


def _flags(p: argparse.ArgumentParser) -> set[str]:
    return {s for a in p._actions for s in a.option_strings if s.startswith("--")}


# --- the runs -----------------------------------------------------------------------------


def _start(args: argparse.Namespace, stage: str) -> None:
    """``--threads``; and, launched by torchrun (one process of several), the process
    group and this process's GPU (the generative and motion stages only, so far)."""
    import torch

    if args.threads:
        torch.set_num_threads(args.threads)
    if int(os.environ.get("WORLD_SIZE", "1")) <= 1:
        return
    if stage not in ("generative", "motion"):
        raise LoosefitInputError(
            "torchrun",
            "stage",
            "generative or motion (the stages that train on several processes so far)",
            stage,
        )
    import torch.distributed as dist

    if not dist.is_initialized():
        dist.init_process_group("nccl" if args.device.startswith("cuda") else "gloo")
    if args.device.startswith("cuda"):
        args.device = f"cuda:{int(os.environ.get('LOCAL_RANK', '0'))}"


def _physics_weights(loss, args: argparse.Namespace):
    """A loss config with the physics weights given (``--membrane``, ``--bending``,
    ``--collision``, ``--flare``, ``--speed``: those the stage has), checked as the config
    checks its weights."""
    names = ("membrane", "bending", "collision", "flare", "speed")
    given = {n: getattr(args, n, None) for n in names}
    return dataclasses.replace(loss, **{n: v for n, v in given.items() if v is not None})


def _finish(out, report: dict, kept: str = "model") -> int:
    """A finished training run: its report, and where the run and its ``kept``.pt are
    (under torchrun, the first process's to say: the others return 0 quietly)."""
    import torch.distributed as dist

    from loosefit.api import process_rank

    rank = process_rank()
    if dist.is_available() and dist.is_initialized():  # torchrun: every process, once done
        dist.destroy_process_group()
    if rank > 0:
        return 0
    print(Path(out, "report.md").read_text())
    log(f"run in {out}; {kept} {Path(out, kept + '.pt')}")
    return 0 if report else 1


def run_generative(args: argparse.Namespace) -> int:
    from loosefit.api import train_generative, training_config

    _start(args, "generative")
    cfg = training_config(
        "generative",
        args.preset,
        decoder=args.decoder,
        basis_size=args.basis_size,
        **_common_overrides(args),
        precision=args.precision,
        mirror=True if args.mirror else None,
    )
    cfg.loss = _physics_weights(cfg.loss, args)
    if args.kl is not None:
        cfg.loss = dataclasses.replace(cfg.loss, kl=args.kl)
    cfg.init = args.init
    out = args.out or f"runs/generative-{args.preset}-{cfg.model.decoder}"
    report = train_generative(cfg, args.data, out, log=log)
    return _finish(out, report, "checkpoint")


def run_motion(args: argparse.Namespace) -> int:
    from loosefit.api import train_motion, training_config

    _start(args, "motion")
    if not args.generative:
        raise LoosefitInputError(
            "loosefit train motion",
            "--generative",
            "the trained generative model's checkpoint",
            "none",
        )
    cfg = training_config(
        "motion",
        args.preset,
        **_common_overrides(args),
        previous=args.previous,
        previous_state=False if args.no_previous_state else None,
        mirror=True if args.mirror else None,
        unroll=True if args.unroll else None,
        joints=args.joints,
        precision=args.precision,
    )
    cfg.loss = _physics_weights(cfg.loss, args)
    cfg.init = args.init
    kind = "ps" if cfg.model.previous_state else "nops"
    out = args.out or f"runs/motion-{args.preset}-{kind}"
    # a data set simulated before the simulator recorded its drape: settled here, once
    report = train_motion(cfg, args.data, args.generative, out, log=log, settle=True)
    return _finish(out, report)


def run_detail(args: argparse.Namespace) -> int:
    from loosefit.api import train_detail, training_config

    _start(args, "detail")
    if not args.motion:
        raise LoosefitInputError(
            "loosefit train detail", "--motion", "the trained motion stage's model.pt", "none"
        )
    cfg = training_config(
        "detail",
        args.preset,
        **_common_overrides(args),
        discriminator=False if args.no_discriminator else None,
    )
    if args.edge_weight is not None:
        cfg.loss.edge = args.edge_weight
    cfg.init = args.init
    kind = ("full" if cfg.discriminator else "nodisc") + ("-edge" if cfg.loss.edge else "")
    out = args.out or f"runs/detail-{args.preset}-{kind}"
    report = train_detail(cfg, args.data, args.motion, out, generative=args.generative, log=log)
    return _finish(out, report)


def run_baseline(args: argparse.Namespace) -> int:
    from loosefit.api import train_baseline, training_config

    _start(args, "baseline")
    if not args.method:
        raise LoosefitInputError(
            "loosefit train baseline", "--method", "santesteban or virtual-bones", "none"
        )
    cfg = training_config(
        "baseline",
        args.preset,
        method=args.method,
        **_common_overrides(args),
        mirror=True if args.mirror else None,
        joints=args.joints,
        bones=args.bones,
    )
    out = args.out or f"runs/baseline-{args.preset}-{args.method}"
    return _finish(out, train_baseline(cfg, args.data, out, log=log))


def run_engine(args: argparse.Namespace) -> int:
    from loosefit.api import pretrained_checkpoint, train_engine, training_config

    _start(args, "engine")
    cfg = training_config(
        "engine",
        args.preset,
        **_common_overrides(args),
        basis=args.basis,
        targets=args.targets,
        mirror=False if args.no_mirror else None,
        membrane=args.membrane_weight,
        procedural=args.procedural,
        noise=args.noise,
        noise_correlation=args.noise_correlation,
        samples=args.samples,
    )
    out = args.out or f"runs/engine-{args.preset}"
    motion = args.motion or pretrained_checkpoint()
    report = train_engine(cfg, args.data, motion, out, log=log)
    return _finish(out, report, "engine")


def run_residual(args: argparse.Namespace) -> int:
    from loosefit.api import pretrained_checkpoint
    from loosefit.api.train import fit_residual

    _start(args, "residual")
    motion = args.motion or pretrained_checkpoint()
    path = fit_residual(
        motion,
        args.data,
        args.out,
        directions=args.directions,
        correlation=args.correlation,
        scale=args.scale,
        gain=not args.no_gain,
        log=log,
    )
    log(f"residual process in {path}")
    return 0
