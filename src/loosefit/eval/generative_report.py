"""The generative model's ablation (the paper's Fig. 4) as a table.

:data:`DECODERS`: the decoders compared; :func:`format_table`: one row per decoder and
seed of their held-out figures, then mean and half range per decoder.
"""

from __future__ import annotations

import numpy as np

DECODERS = {
    "decomposed": "ours: D_rec + D_dyn (deformation decomposition)",
    "vertex": "single vertex decoder, symmetric to the encoder",
    "ssdr": "linear decoder on a skinning decomposition (SSDR)",
}


def spread(values: list[float]) -> dict:
    """Mean, and half the range (the run-to-run noise with two seeds), of a metric."""
    v = np.asarray(values, float)
    return {"mean": float(v.mean()), "half_range": float(np.ptp(v) / 2), "values": v.tolist()}


def format_table(rows: dict[str, list[dict]], data: str, preset: str) -> str:
    """The Markdown table: one row per decoder and seed, then mean +- half range per decoder."""
    first = next(iter(rows.values()))[0]
    lines = [
        f"Held-out clips of `{data}`, preset `{preset}`, {first['epochs']} epochs each; "
        "lengths in cm, STED unitless.",
        "",
        "| decoder | seed | test RMSE (cm) | test Hausdorff (cm) | test STED | train RMSE (cm) |"
        " parameters | s/epoch |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for decoder, runs in rows.items():
        for r in runs:
            t = r["test"]
            lines.append(
                f"| {DECODERS[decoder]} | {r['seed']} | {t['rmse_cm']:.3f} | "
                f"{t['hausdorff_cm']:.3f} | {t['sted']:.4f} | {r['train']['rmse_cm']:.3f} | "
                f"{r['parameters']:,} | {r['seconds_per_epoch'] or float('nan'):.2f} |"
            )
    if any(len(runs) > 1 for runs in rows.values()):
        lines += [
            "",
            "| decoder | seeds | test RMSE (cm), mean +- half range | test Hausdorff (cm), mean"
            " | test STED, mean |",
            "|---|---:|---:|---:|---:|",
        ]
        for decoder, runs in rows.items():
            s = spread([r["test"]["rmse_cm"] for r in runs])
            h = np.mean([r["test"]["hausdorff_cm"] for r in runs])
            st = np.mean([r["test"]["sted"] for r in runs])
            lines.append(
                f"| {DECODERS[decoder]} | {len(runs)} | {s['mean']:.3f} +- "
                f"{s['half_range']:.3f} | {h:.3f} | {st:.4f} |"
            )
    lines += ["", f"Machine: {first['machine']}.", ""]
    return "\n".join(lines)
