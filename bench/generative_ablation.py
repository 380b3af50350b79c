"""The generative model and its two ablations (paper 4.2, Fig. 4) on one dataset: one table.

Trains (or resumes, or reuses finished runs of) the decomposed model, the single
vertex decoder and the linear decoder on a skinning decomposition, with the same
preset, then writes their reconstruction errors on the held-out clips as a
Markdown table::

    python bench/generative_ablation.py --data datasets/demo --preset cpu \
        --out runs/ablation-demo --table docs/GENERATIVE_TABLE.md
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from loosefit.train.generative import TrainGenerativeConfig, train_generative

DECODERS = {
    "decomposed": "ours: D_rec + D_dyn (deformation decomposition)",
    "vertex": "single vertex decoder, symmetric to the encoder",
    "ssdr": "linear decoder on a skinning decomposition (SSDR)",
}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", default="datasets/demo")
    p.add_argument("--preset", default="cpu", help="cpu or full")
    p.add_argument("--epochs", type=int, default=None)
    p.add_argument("--out", default="runs/ablation-demo")
    p.add_argument("--table", default=None, help="write the table here (Markdown)")
    p.add_argument("--device", default="cpu")
    args = p.parse_args()
    rows = []
    for decoder in DECODERS:
        run = Path(args.out) / decoder
        report_path = run / "report.json"
        if report_path.is_file():
            report = json.loads(report_path.read_text())
        else:
            cfg = TrainGenerativeConfig.preset(
                args.preset, decoder=decoder, epochs=args.epochs, device=args.device
            )
            report = train_generative(args.data, run, cfg)
        rows.append((decoder, report))
    lines = [
        f"Held-out clips of `{Path(args.data).name}`, preset `{args.preset}`, "
        f"{rows[0][1]['epochs']} epochs each; lengths in cm, STED unitless.",
        "",
        "| decoder | test RMSE (cm) | test Hausdorff (cm) | test STED | train RMSE (cm) |"
        " parameters | s/epoch |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for decoder, r in rows:
        t = r["test"]
        lines.append(
            f"| {DECODERS[decoder]} | {t['rmse_cm']:.3f} | {t['hausdorff_cm']:.3f} | "
            f"{t['sted']:.4f} | {r['train']['rmse_cm']:.3f} | {r['parameters']:,} | "
            f"{r['seconds_per_epoch']:.2f} |"
        )
    lines += ["", f"Machine: {rows[0][1]['machine']}.", ""]
    text = "\n".join(lines)
    print(text)
    if args.table:
        Path(args.table).write_text(text)


if __name__ == "__main__":
    main()
