"""The generative model and its two ablations (paper 4.2, Fig. 4) on one dataset: one table.

Trains (or resumes, or reuses finished runs of) the decomposed model, the single
vertex decoder and the linear decoder on a skinning decomposition, with the same
preset, each with every seed asked for, then writes their reconstruction errors on
the held-out clips as a Markdown table (per seed, and the mean and spread over the
seeds, which is the run-to-run noise a difference must beat)::

    python bench/ablations/generative_ablation.py --data datasets/demo --preset cpu \
        --out runs/ablation-demo --table docs/design/notes/GENERATIVE_TABLE.md
    python bench/ablations/generative_ablation.py --data datasets/salsa --preset cpu --epochs 40 \
        --seeds 0,1 --out runs/salsa/ablation --json runs/salsa/ablation/table.json

Seed 0's run of a decoder lives in ``OUT/DECODER``, seed k's in ``OUT/DECODER-sK``.
``--train-only`` trains the missing runs and writes nothing else (to split the
work over processes: ``--decoders`` picks theirs).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import torch

from loosefit.eval.generative_report import DECODERS, format_table, spread
from loosefit.train.generative import TrainGenerativeConfig, train_generative


def run_dir(out: Path, decoder: str, seed: int) -> Path:
    """Where seed ``seed``'s run of ``decoder`` lives."""
    return out / (decoder if seed == 0 else f"{decoder}-s{seed}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", default="datasets/demo")
    p.add_argument("--preset", default="cpu", help="cpu or full")
    p.add_argument("--epochs", type=int, default=None)
    p.add_argument("--seeds", default="0", help="comma-separated training seeds")
    p.add_argument("--decoders", default=",".join(DECODERS), help="comma-separated decoders")
    p.add_argument("--out", default="runs/ablation-demo")
    p.add_argument("--table", default=None, help="write the table here (Markdown)")
    p.add_argument("--json", default=None, help="write the figures here (JSON)")
    p.add_argument("--train-only", action="store_true", help="train missing runs, no table")
    p.add_argument("--threads", type=int, default=0, help="torch CPU threads (0: default)")
    p.add_argument("--device", default="cpu")
    args = p.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    seeds = [int(s) for s in args.seeds.split(",")]
    decoders = [d for d in args.decoders.split(",") if d]
    rows: dict[str, list[dict]] = {}
    for seed in seeds:
        for decoder in decoders:
            run = run_dir(Path(args.out), decoder, seed)
            report_path = run / "report.json"
            if report_path.is_file():
                report = json.loads(report_path.read_text())
            else:
                cfg = TrainGenerativeConfig.preset(
                    args.preset,
                    decoder=decoder,
                    epochs=args.epochs,
                    device=args.device,
                    seed=seed,
                )
                report = train_generative(args.data, run, cfg)
            rows.setdefault(decoder, []).append({"seed": seed, **report})
    if args.train_only:
        return
    text = format_table(rows, Path(args.data).name, args.preset)
    print(text)
    if args.table:
        Path(args.table).write_text(text)
    if args.json:
        summary = {
            d: {
                "runs": [
                    {
                        k: r[k]
                        for k in ("seed", "epochs", "parameters", "seconds_per_epoch", "machine")
                    }
                    | {"test": _brief(r["test"]), "train": _brief(r["train"])}
                    for r in runs
                ],
                "test_rmse_cm": spread([r["test"]["rmse_cm"] for r in runs]),
            }
            for d, runs in rows.items()
        }
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(summary, indent=1))


def _brief(split: dict) -> dict:
    return {k: split[k] for k in ("frames", "rmse_cm", "hausdorff_cm", "sted")}


if __name__ == "__main__":
    main()
