"""A trained model's held-out rollout error beside its two references (docs/use/YOUR_GARMENT.md):
the settled drape carried rigidly by the root (no dynamics), and the generative model's own
reconstruction of the simulation (the floor under the motion encoder).

    .venv/bin/python bench/quality/rollout_references.py --checkpoint runs/dress/package/motion.pt \
        --data datasets/dress
"""

from __future__ import annotations

import argparse
import json
import platform
import sys

import torch

import loosefit
from loosefit.data.format import DatasetReader
from loosefit.eval.rollouts import evaluate_rollouts


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--checkpoint", required=True)
    ap.add_argument("--data", required=True)
    ap.add_argument("--split", default="test")
    ap.add_argument("--out", default=None, help="also write the figures here (JSON)")
    args = ap.parse_args()
    model, reader = loosefit.load(args.checkpoint).model, DatasetReader(args.data)
    rows = {}
    for name, kw in (
        ("model", {}),
        ("rigid drape", {"reference": True}),
        ("reconstruction (floor)", {"oracle": True}),
    ):
        r = evaluate_rollouts(model, reader, args.split, surface=False, **kw)
        rows[name] = {"rmse_cm": r["rmse_cm"], "frames": r["frames"]}
    rows["machine"] = (
        f"{platform.machine()}, {torch.get_num_threads()} threads, torch {torch.__version__}"
    )
    print(json.dumps(rows, indent=1))
    if args.out:
        with open(args.out, "w") as f:
            json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
