"""The penetration regression set: simulate it, judge every clip, write the table.

Simulates the motions of ``configs/regression.yaml`` (the ground truth's hard cases: the
deep crouch of salsa 60_02, mirrored and faster, 60_01's crouch, a fast spin) as a data set,
once per variant of the cloth configuration, and reports per clip what its targets
name: the share of garment vertices inside the body (any depth: mean and 99th percentile over
frames), the worst frame's share deeper than 5 mm, the deepest vertex, edge strain p99,
seconds per frame and whether the clip is kept (no vertex deeper than 3 cm, at most 1 %
deeper than 5 mm in any frame); and, to tell the cloth's failures from the body model's, how
much of the inside mean falls in frames whose pose folds into itself (a thigh inside the
belly) and the inside mean against the flattened collider the cloth met. Each variant's data
set resumes where a killed run stopped (a finished one is only judged again).

    .venv/bin/python bench/data/penetration_regression.py                       # the default cloth
    .venv/bin/python bench/data/penetration_regression.py --variants before,after --workers 2
    # the flagged salsa takes whole, and new motion (mirrored and faster, a fast dance)
    .venv/bin/python bench/data/penetration_regression.py --config configs/salsa_takes.yaml \
        --out runs/salsa_takes

Variants: ``after`` is the default configuration; ``flatten`` the same without the pose
correction (``unfold``); ``before`` without either (the capture and the collider as posed).
About 35 core-minutes per variant on dev-cpu.
Exit status 1 when a clip of the last variant is not kept.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import sys
import time
from pathlib import Path

import torch

from loosefit.data.format import DatasetReader, write_json_atomic
from loosefit.eval.dataset_quality import judge_dataset
from loosefit.garment.quality import PENETRATION_TOLERANCE
from loosefit.sim.dataset_config import read_config_file
from loosefit.sim.generate import generate
from loosefit.train.frames import avatar_for

ROOT = Path(__file__).resolve().parents[2]
VARIANTS = {
    "after": {},  # the defaults: the pose correction and the flattened collider
    # the defaults before the pose correction (loosefit.motion.pose_correction)
    "flatten": {"unfold": {"enabled": False}},
    "before": {"cloth": {"flatten_overlaps": False}, "unfold": {"enabled": False}},
    # the experiments on the way to the flattened collider (docs/design/PENETRATION.md)
    "gap4": {"cloth": {"body_contact_gap": 0.04}, "unfold": {"enabled": False}},
    "clear4": {"cloth": {"overlap_inset": -0.004}, "unfold": {"enabled": False}},
}


def table(results: dict) -> str:
    lines = [
        "| variant | clip | frames | inside mean % | of it in folded poses % | inside mean, "
        "collider % | inside p99 % | > 5 mm, worst frame % | deepest cm | strain p99 | "
        "s/frame | pose overlap: frames, deepest cm | kept |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for variant, rows in results.items():
        for name, r in rows.items():
            if "frames" not in r:
                lines.append(
                    f"| {variant} | {name} | | | | | | | | | | | {r['status']}: {r['reason']} |"
                )
                continue
            spf = r["seconds_per_frame"]
            overlap = (
                f"{r['overlap_frames']}, {r['overlap_depth_cm']:.2f}"
                if r["overlap_frames"] is not None
                else "-"
            )
            lines.append(
                f"| {variant} | {name} | {r['frames']} | {r['inside_mean_pct']:.3f} | "
                f"{r['inside_folded_pct']:.3f} | {r['inside_collider_pct']:.3f} | "
                f"{r['inside_p99_pct']:.2f} | {r['deep_max_pct']:.2f} | "
                f"{r['depth_max_cm']:.2f} | {r['strain_p99']:.3f} | "
                f"{spf:.2f} | {overlap} | {'yes' if r['kept'] else '**no**'} |"
            )
    return "\n".join(lines)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", default=str(ROOT / "configs" / "regression.yaml"))
    ap.add_argument("--variants", default="after", help=f"comma-separated, of {list(VARIANTS)}")
    ap.add_argument("--out", default=str(ROOT / "runs" / "regression"))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", default=None, help="also write the figures here")
    ap.add_argument("--only", default="", help="only the clips whose spec holds this text")
    args = ap.parse_args()

    torch.set_num_threads(1)
    results = {}
    for variant in args.variants.split(","):
        if variant not in VARIANTS:
            print(f"unknown variant {variant!r}: expected one of {list(VARIANTS)}")
            return 2
        config = read_config_file(args.config)
        change = VARIANTS[variant]
        config.cloth = dataclasses.replace(config.cloth, **change.get("cloth", {}))
        config.unfold = dataclasses.replace(config.unfold, **change.get("unfold", {}))
        config.preset = f"regression-{variant}"
        if args.only:
            config.motions.specs = tuple(x for x in config.motions.specs if args.only in x)
        folder = Path(args.out) / variant
        t0 = time.perf_counter()
        generate(config, folder, workers=args.workers, progress=True)
        print(f"{variant}: simulated in {time.perf_counter() - t0:.0f} s", flush=True)
        reader = DatasetReader(folder, allow_incomplete=True)
        results[variant] = judge_dataset(reader, avatar_for(reader))
    print(
        f"machine: {platform.platform()}, {os.cpu_count()} CPUs; tolerance "
        f"{PENETRATION_TOLERANCE * 1000:.0f} mm"
    )
    print(table(results))
    if args.json:
        write_json_atomic(Path(args.json), results)
    last = results[list(results)[-1]]
    return 0 if all(r.get("kept") for r in last.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
