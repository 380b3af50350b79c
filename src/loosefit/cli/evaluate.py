"""``loosefit evaluate``: roll out held-out clips and compare them with the simulation."""

from __future__ import annotations

import argparse
from pathlib import Path

from loosefit.cli.common import (
    add_generative_arg,
    add_stage_args,
    add_threads_arg,
    inference_threads,
    log,
    stages,
    threads_of,
)
from loosefit.errors import LoosefitInputError


def add_parser(sub) -> None:
    p = sub.add_parser("evaluate", help="roll out held-out clips and compare with the simulation")
    p.add_argument("--checkpoint", required=True, help="a motion run's model.pt or checkpoint.pt")
    add_generative_arg(p)
    p.add_argument(
        "--data",
        nargs="+",
        default=["datasets/salsa"],
        help="a dataset folder, or sequence .npz files (the ground truth of their "
        "motions, e.g. from loosefit.simulate)",
    )
    p.add_argument(
        "--members",
        nargs="+",
        default=[],
        metavar="DATASET",
        help="data sets of the same clips simulated from other seeds (loosefit simulate "
        "--seeds): scores every model against each clip's members too (the simulation's own "
        "spread, RMSE to their mean, the energy score, hem flare and speed against their "
        "range, the raised knee); members inside --data (NAME@seedS) count without it",
    )
    p.add_argument("--split", default="test", help="with a dataset: train, test or all")
    p.add_argument("--horizons", default="100,500,1200", help="frames for iter-N errors")
    p.add_argument("--max-frames", type=int, default=None, help="roll out at most this many")
    p.add_argument("--rmse-only", action="store_true", help="skip Hausdorff and STED (faster)")
    p.add_argument("--out", default="out/evaluate")
    add_stage_args(p)
    add_threads_arg(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from loosefit.cli.common import open_model
    from loosefit.data.format import DatasetReader, read_any_sequence
    from loosefit.eval.ensemble import evaluate_ensemble
    from loosefit.eval.ensemble_members import gather_ensembles
    from loosefit.eval.report import write_rollout_report
    from loosefit.eval.rollouts import evaluate_rollouts

    threads_of(args)  # a bad count before the work
    model = open_model(args.checkpoint, args.generative, args.detail).model
    if len(args.data) == 1 and Path(args.data[0]).is_dir():
        reader = DatasetReader(args.data[0])
        where = str(Path(args.data[0]).resolve())
    else:  # sequences: the ground truth of each motion
        reader = {Path(f).stem: read_any_sequence(f) for f in args.data}
        where = [str(Path(f).resolve()) for f in args.data]
    gathered = None  # each clip's members, checked before any rollout
    if args.members and not isinstance(reader, DatasetReader):
        raise LoosefitInputError(
            "--members", "--data", "a data set folder to gather members with", "sequence files"
        )
    if isinstance(reader, DatasetReader) and (args.members or has_members(reader, args.split)):
        gathered = gather_ensembles([args.data[0], *args.members], args.split)
    try:
        horizons = tuple(int(h) for h in args.horizons.split(","))
    except ValueError:
        raise LoosefitInputError(
            "--horizons", "horizons", "comma-separated frame counts", repr(args.horizons)
        ) from None
    with inference_threads(args):
        result = evaluate_rollouts(
            model,
            reader,
            args.split,
            horizons=horizons,
            surface=not args.rmse_only,
            max_frames=args.max_frames,
            stages=stages(args),
        )
    result["checkpoint"] = str(Path(args.checkpoint).resolve())
    result["dataset"] = where
    if gathered is not None:
        with inference_threads(args):
            result["ensemble"] = evaluate_ensemble(
                {Path(args.checkpoint).parent.name: model},
                [args.data[0], *args.members],
                args.split,
                surface=not args.rmse_only,
                stages=stages(args),
                progress=log,
                ensembles=gathered,
            )
    write_rollout_report(result, args.out, f"Rollouts of {Path(args.checkpoint).parent.name}")
    print(Path(args.out, "evaluation.md").read_text())
    log(f"wrote {args.out}/evaluation.{{md,csv,json}} and rmse_per_frame.png")
    return 0


def has_members(reader, split: str) -> bool:
    """Whether a data set holds a clip of ``split`` simulated from more than one seed."""
    from loosefit.eval.ensemble_members import member_clip

    names = reader.split(split)
    return any(member_clip(n)[1] is not None for n in names)
