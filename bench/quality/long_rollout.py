"""A rollout of 10,000 frames: does the learned garment stay on the body, and does its error
grow? (docs/design/RELIABILITY.md)

The held-out salsa chain (never trained on) is played ``--repeats`` times in a row
(:func:`~loosefit.motion.chain.chain_motions`, half-second blends between), and the packaged
model rolls the whole of it out in one go. Each repetition is scored against the simulation
of the chain, in the body's root frame (so where the chain placed the repetition on the
floor does not matter); the blends have no ground truth and are left out. Reported: RMSE
per repetition and per 1,000-frame block, whether every frame is finite, and the farthest
any garment vertex gets from the root joint.

    .venv/bin/python bench/quality/long_rollout.py            # about 4 min on dev-cpu
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np
import torch

import loosefit
from loosefit.data.format import DatasetReader
from loosefit.model.motion_features import garment_in_root_frame
from loosefit.motion.chain import chain_motions

# the figures of a page docs/X.md as JSON: bench/figures/X.json
FIGURES = Path(__file__).resolve().parents[1] / "figures"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--checkpoint", default="checkpoints/salsa/motion.pt")
    ap.add_argument("--data", default="datasets/salsa")
    ap.add_argument("--clip", default=None, help="default: the data set's first test clip")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", default="docs/img/long_rollout")
    args = ap.parse_args()

    reader = DatasetReader(args.data)
    name = args.clip or reader.split("test")[0]
    seq = reader.read(name)
    model = loosefit.load(args.checkpoint).model
    chain = chain_motions([seq.motion] * args.repeats, name=f"{name} x{args.repeats}")
    t0 = time.perf_counter()
    result = model.animate(chain)
    seconds = time.perf_counter() - t0
    g = result.vertices  # (T, V, 3)
    truth = garment_in_root_frame(seq.motion, seq.garment_vertices).numpy()
    per_frame = np.full(len(g), np.nan)  # cm, NaN in the blends
    reps = []
    for _, first, n in chain.meta["segments"]:
        part = chain.slice(first, first + n)
        pred = garment_in_root_frame(part, g[first : first + n]).numpy()
        err = 100 * np.sqrt(((pred - truth) ** 2).sum(-1).mean(-1))  # (n,) cm
        per_frame[first : first + n] = err
        reps.append(float(np.sqrt(np.mean(err**2))))
    blocks = []
    for start in range(0, len(g), 1000):
        e = per_frame[start : start + 1000]
        e = e[np.isfinite(e)]
        if len(e):
            blocks.append(
                {
                    "frames": f"{start}-{min(start + 1000, len(g)) - 1}",
                    "rmse_cm": float(np.sqrt(np.mean(e**2))),
                }
            )
    root = chain.root_translation[:, None, :]
    report = {
        "checkpoint": args.checkpoint,
        "clip": name,
        "frames": int(len(g)),
        "repeats": args.repeats,
        "finite": bool(np.isfinite(g).all()),
        "farthest_from_root_m": float(np.linalg.norm(g - root, axis=-1).max()),
        "rmse_per_repeat_cm": reps,
        "rmse_per_1000_frames_cm": blocks,
        "frames_per_second": len(g) / seconds,
        "machine": f"{platform.machine()}, {torch.get_num_threads()} threads, torch "
        f"{torch.__version__}",
    }
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    (FIGURES / f"{out.stem}.json").write_text(json.dumps(report, indent=2))

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(10, 3.2), dpi=120)
    ax.plot(per_frame, lw=0.6, color="tab:orange")
    for rmse, (_, first, n) in zip(reps, chain.meta["segments"], strict=True):
        ax.hlines(rmse, first, first + n, color="black", lw=1.2)
    ax.set_xlabel("frame of the rollout (30 fps)")
    ax.set_ylabel("RMSE per frame (cm)")
    ax.set_title(
        f"{args.repeats} x the held-out chain {name} in one rollout of {len(g)} frames "
        "(black: RMSE of each repetition)",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(out.with_suffix(".png"))
    print(json.dumps({k: v for k, v in report.items() if k != "rmse_per_1000_frames_cm"}, indent=1))
    print("| frames | RMSE (cm) |\n|---|---:|")
    for b in blocks:
        print(f"| {b['frames']} | {b['rmse_cm']:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
