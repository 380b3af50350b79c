"""Drift of a long rollout, measured on the same frames: restarted from the simulation every
N frames against one unbroken rollout.

Table 1's iter-N is the RMSE over a sequence's first N frames, so it mixes two things:
error that compounds over a rollout, and motion that is harder later in the sequence.
Here every row scores the same frames (a whole held-out clip), and only how long ago the
rollout last saw a true garment changes: every frame is predicted at most N frames after
the simulated garment was given as its previous state (N = 100, 500, 1,200, or never). The
GRU's state depends on the motion alone, so it runs on unchanged through a restart::

    python bench/quality/motion_drift.py --data datasets/salsa --runs runs/salsa/motion \
        --table docs/results/MOTION_DRIFT.md

Each run's errors are kept in its folder (``drift.json``, tied to its ``model.pt`` by a
hash and to the data set's folder and held-out clips), so a table of many runs recomputes
only the runs that are new or retrained.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import platform
from pathlib import Path

import torch
import yaml

from loosefit.data.format import DatasetReader
from loosefit.eval.rollouts import evaluate_rollouts
from loosefit.inference.animator import load_animation_model
from loosefit.inference.stages import MOTION_ONLY

EVERY = (1, 100, 500, 1200, None)
# the Table 1 runs: name -> (label, the overrides each trained with)
RUNS_FILE = Path(__file__).resolve().parents[1] / "ablations" / "motion_runs.yaml"
RUNS = {
    key: (run["label"], run["overrides"])
    for key, run in yaml.safe_load(RUNS_FILE.read_text(encoding="utf-8")).items()
}


def _drift(path: Path, reader: DatasetReader) -> tuple[dict, int]:
    """RMSE (cm) per restart interval of the model at ``path``, and the frames scored."""
    cache = path.parent / "drift.json"
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    key = {"model_sha256": digest, "data": str(reader.root.resolve()), "test": reader.split("test")}
    if cache.is_file():
        saved = json.loads(cache.read_text())
        if all(saved.get(k) == v for k, v in key.items()):
            return {e: saved["rmse_cm"][str(e)] for e in EVERY}, saved["frames"]
    model = load_animation_model(path)
    errors, frames = {}, 0
    for every in EVERY:
        result = evaluate_rollouts(
            model, reader, "test", surface=False, restart_every=every, stages=MOTION_ONLY
        )
        errors[every], frames = result["rmse_cm"], result["frames"]
    cache.write_text(
        json.dumps({**key, "frames": frames, "rmse_cm": {str(e): v for e, v in errors.items()}})
    )
    return errors, frames


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", default="datasets/salsa")
    p.add_argument("--runs", default="runs/salsa/motion", help="folder of the Table 1 runs")
    p.add_argument("--table", default=None, help="write the table here (Markdown)")
    p.add_argument("--threads", type=int, default=0)
    p.add_argument("--only", default=",".join(RUNS), help=f"which of {list(RUNS)}")
    args = p.parse_args()
    if args.threads > 0:
        torch.set_num_threads(args.threads)
    reader = DatasetReader(args.data)
    rows, frames = [], 0
    for key in args.only.split(","):
        label = RUNS[key][0]
        path = Path(args.runs) / key / "model.pt"
        if not path.is_file():
            print(f"skipping {key}: no {path}")
            continue
        errors, frames = _drift(path, reader)
        for every in EVERY:
            print(f"{key}: N = {every}: {errors[every]:.3f} cm", flush=True)
        cells = [f"{errors[e]:.3f}" for e in EVERY]
        cells += [f"{100 * (errors[e] / errors[100] - 1):+.1f}%" for e in (1200, None)]
        rows.append(f"| {label} | " + " | ".join(cells) + " |")
    lines = [
        f"Held-out clips of `{Path(args.data).name}` ({', '.join(reader.split('test'))}): "
        f"RMSE (cm) over all {frames} frames of rollouts restarted "
        "from the simulated garment every N frames (every frame is predicted at most N "
        "frames after a true state), against one unbroken rollout. The same frames in every "
        "column: the difference is drift alone. N = 1 gives every frame the true previous "
        "garment (teacher forcing): what the previous state is worth when it is right.",
        "",
        "| method | N = 1 | N = 100 | N = 500 | N = 1,200 | unbroken | 1,200 vs 100 "
        "| unbroken vs 100 |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    lines += rows
    lines += ["", f"Machine: {platform.machine()}, torch {torch.__version__}, cpu."]
    text = "\n".join(lines) + "\n"
    print(text)
    if args.table:
        Path(args.table).write_text(text)


if __name__ == "__main__":
    main()
