"""Table 1 of the paper: held-out rollout RMSE at 100/500/1,200 frames with and without the
previous state, plus teacher forcing only (how the previous state is trained), one table.

Trains (or resumes, or reuses finished runs of) the motion encoder in each configuration on
the same frozen generative model, rolls every held-out clip out from its first frame, and
writes the table::

    python bench/ablations/motion_ablation.py --data datasets/salsa \
        --generative runs/generative-salsa-cpu/checkpoint.pt --preset cpu \
        --out runs/motion-ablation-salsa --table docs/results/MOTION_TABLE.md

Runs can train side by side (``--runs ps --threads 1 --no-table`` in one process,
``--runs nops ...`` in another); a last call with every run then only writes the table.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

import torch
import yaml

from loosefit.data.format import DatasetReader
from loosefit.eval.report import write_rollout_report
from loosefit.eval.rollouts import HORIZONS, evaluate_rollouts
from loosefit.inference.animator import load_animation_model
from loosefit.inference.stages import MOTION_ONLY
from loosefit.sim.rest_drape import settled_rest_drape
from loosefit.train.motion import TrainMotionConfig, train_motion

RUNS_FILE = Path(__file__).with_name("motion_runs.yaml")  # the runs Table 1 compares
RUNS = {  # name: (the table's label, the overrides of TrainMotionConfig)
    key: (run["label"], run["overrides"])
    for key, run in yaml.safe_load(RUNS_FILE.read_text(encoding="utf-8")).items()
}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", default="datasets/salsa")
    p.add_argument(
        "--datasets",
        default=None,
        help="the folder of the other data sets some runs "
        "train on (salsa-speed, salsa-speeds; default: --data's folder)",
    )
    p.add_argument("--generative", required=True, help="the generative checkpoint")
    p.add_argument("--preset", default="cpu", help="cpu or full")
    p.add_argument("--epochs", type=int, default=None)
    p.add_argument("--runs", default=",".join(RUNS), help=f"which of {list(RUNS)}")
    p.add_argument("--out", default="runs/motion-ablation")
    p.add_argument("--table", default=None, help="write the table here (Markdown)")
    p.add_argument("--device", default="cpu")
    p.add_argument("--threads", type=int, default=0, help="torch CPU threads (0: default)")
    p.add_argument(
        "--no-table",
        action="store_true",
        help="train and evaluate only; e.g. one "
        "run per process, side by side, then one call for the table",
    )
    args = p.parse_args()
    if args.threads > 0:
        torch.set_num_threads(args.threads)
    reader = DatasetReader(args.data)
    rows = []
    for key in args.runs.split(","):
        label, overrides = RUNS[key]
        overrides = dict(overrides)
        data = args.data  # every run is scored on --data's held-out clips
        if "dataset" in overrides:  # trained on another data set with the same held-out chain
            data = str(Path(args.datasets or Path(args.data).parent) / overrides.pop("dataset"))
        run = Path(args.out) / key
        if not (run / "report.json").is_file():
            loss = overrides.pop("loss", {})
            kw = {"epochs": args.epochs, **overrides}  # a run may fix its own epochs
            cfg = TrainMotionConfig.preset(args.preset, device=args.device, **kw)
            cfg.loss = replace(cfg.loss, **loss)
            train_motion(data, args.generative, run, cfg, settle=settled_rest_drape)
        evaluation = run / "evaluation" / "evaluation.json"
        if evaluation.is_file():
            result = json.loads(evaluation.read_text())
        else:
            model = load_animation_model(run / "model.pt", args.generative)
            result = evaluate_rollouts(model, reader, "test", stages=MOTION_ONLY)
            write_rollout_report(result, run / "evaluation", f"Rollouts, {label}")
        report = json.loads((run / "report.json").read_text())
        rows.append((label, result, report))
    if args.no_table:
        return
    # The scale of the errors: the settled drape carried by the root, with no dynamics at all
    # (a rollout that does no better has learned nothing of the motion).
    # And the floor: the generative model's own code of the simulated garment (Z*), decoded,
    # the best any motion encoder can do through the frozen decoders.
    model = None  # loaded once, if either row is not scored yet
    for name, kw, label in (
        (
            "reference",
            dict(reference=True),
            "reference: rest drape carried by the root, no dynamics",
        ),
        ("oracle", dict(oracle=True), "oracle: the simulation's own code Z*, decoded (the floor)"),
    ):
        ref = Path(args.out) / name / "evaluation.json"
        if ref.is_file():
            result = json.loads(ref.read_text())
        else:
            model = model or load_animation_model(
                Path(args.out) / args.runs.split(",")[0] / "model.pt", args.generative
            )
            result = evaluate_rollouts(model, reader, "test", stages=MOTION_ONLY, **kw)
            write_rollout_report(result, ref.parent, label[0].upper() + label[1:])
        rows.append((label, result, None))
    hs = [str(h) for h in HORIZONS]
    lines = [
        f"Held-out clips of `{Path(args.data).name}` ({', '.join(rows[0][1]['clips'])}), "
        f"preset `{args.preset}`, {rows[0][2]['epochs']} epochs unless the row says; RMSE in "
        "cm over the first N frames of a rollout from each clip's first frame (a clip shorter "
        "than N does not count for N).",
        "",
        "| method | "
        + " | ".join(f"iter-{h}" for h in hs)
        + " | 1200 vs 100 | RMSE, all frames | Hausdorff (cm) | STED | s/epoch |",
        "|---|" + "---:|" * len(hs) + "---:|---:|---:|---:|---:|",
    ]
    # Runs may have trained on other machines or thread counts: s/epoch names its own.
    machines = list(dict.fromkeys(rep["machine"] for _, _, rep in rows if rep))
    for label, r, rep in rows:
        h = r["horizons"]
        cells = [f"{h[k]:.3f}" if k in h else "-" for k in hs]
        growth = f"{100 * (h['1200'] / h['100'] - 1):+.1f}%" if "1200" in h and "100" in h else "-"
        lines.append(
            f"| {label} | " + " | ".join(cells) + f" | {growth} | {r['rmse_cm']:.3f} | "
            f"{r['hausdorff_cm']:.3f} | {r['sted']:.4f} | "
            + (f"{rep['seconds_per_epoch']:.1f}" if rep else "-")
            + (f" [{machines.index(rep['machine']) + 1}] |" if rep and len(machines) > 1 else " |")
        )
    if len(machines) == 1:
        lines += ["", f"Machine: {machines[0]}.", ""]
    else:
        listed = "; ".join(f"[{i + 1}] {m}" for i, m in enumerate(machines))
        lines += ["", f"Machines (s/epoch): {listed}.", ""]
    text = "\n".join(lines)
    print(text)
    if args.table:
        Path(args.table).write_text(text)


if __name__ == "__main__":
    main()
