"""``loosefit evaluate``: roll out held-out clips and compare them with the simulation."""

from __future__ import annotations

import argparse

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
    p.add_argument(
        "--realisations",
        type=int,
        default=0,
        metavar="S",
        help="with --members: score a set with a residual process by its realisations "
        "0..S-1 (the energy score with their spread); default 0, its one garment",
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
    from loosefit.api.evaluate import open_evaluation
    from loosefit.cli.common import open_model

    threads_of(args)  # a bad count before the work
    if args.realisations < 0:
        raise LoosefitInputError("--realisations", "realisations", "S >= 0", args.realisations)
    model = open_model(args.checkpoint, args.generative, args.detail)
    evaluation = open_evaluation(model, args.data, split=args.split, members=args.members)
    try:
        horizons = tuple(int(h) for h in args.horizons.split(","))
    except ValueError:
        raise LoosefitInputError(
            "--horizons", "horizons", "comma-separated frame counts", repr(args.horizons)
        ) from None
    with inference_threads(args) as n:
        result = evaluation.rollouts(
            horizons=horizons,
            surface=not args.rmse_only,
            max_frames=args.max_frames,
            stages=stages(args),
            threads=n,
        )
    if evaluation.members is not None:
        with inference_threads(args) as n:
            result["ensemble"] = evaluation.ensemble(
                surface=not args.rmse_only,
                stages=stages(args),
                threads=n,
                progress=log,
                realisations=args.realisations,
            )
    print(evaluation.write_report(result, args.out).read_text())
    log(f"wrote {args.out}/evaluation.{{md,csv,json}} and rmse_per_frame.png")
    return 0
