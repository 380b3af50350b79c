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

    .venv/bin/python bench/penetration_regression.py                       # the default cloth
    .venv/bin/python bench/penetration_regression.py --variants before,after --workers 2
    # the flagged salsa takes whole, and new motion (mirrored and faster, a fast dance)
    .venv/bin/python bench/penetration_regression.py --config configs/salsa_takes.yaml \
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

import numpy as np
import torch

from loosefit.data.format import DatasetReader, write_json_atomic
from loosefit.garment.quality import PENETRATION_TOLERANCE, quality
from loosefit.sim.dataset_config import QualityLimits, read_config_file
from loosefit.sim.generate import generate
from loosefit.sim.manifest import LEGACY_CLOTH

ROOT = Path(__file__).resolve().parents[1]
VARIANTS = {
    "after": {},  # the defaults: the pose correction and the flattened collider
    # the defaults before the pose correction (loosefit.motion.pose_correction)
    "flatten": {"unfold": {"enabled": False}},
    "before": {"cloth": {"flatten_overlaps": False}, "unfold": {"enabled": False}},
    # the experiments on the way to the flattened collider (docs/PENETRATION.md)
    "gap4": {"cloth": {"body_contact_gap": 0.04}, "unfold": {"enabled": False}},
    "clear4": {"cloth": {"overlap_inset": -0.004}, "unfold": {"enabled": False}},
}


def judge(folder: Path) -> dict:
    """Per clip figures of a simulated data set, from its sequences and posed bodies.

    Besides the quality figures, the share of the inside mean that falls in frames whose
    pose folds into itself (a limb inside the rest of the body, the frames the collider
    is flattened in: :func:`~loosefit.sim.overlap.flatten_overlaps`), and the inside mean
    measured against that flattened collider, the body the cloth actually met.
    """
    from loosefit.body.regions import body_parts
    from loosefit.geometry.query import closest_points
    from loosefit.sim.overlap import flatten_overlaps
    from loosefit.train.frames import avatar_for

    reader = DatasetReader(folder, allow_incomplete=True)
    avatar = avatar_for(reader)
    # a data set made before a cloth field existed was made with LEGACY_CLOTH's value
    cloth = {**LEGACY_CLOTH, **reader.manifest["config"]["cloth"]}
    arms = cloth.get("arm_collision", False)
    faces = avatar.collider_faces(arms=arms).cpu().numpy()
    parts = body_parts(avatar, arms=arms)
    limits = QualityLimits(**reader.manifest["config"].get("limits", {}))
    rows = {}
    for name, entry in reader.manifest["sequences"].items():
        if "quality" not in entry:
            rows[name] = {"status": entry.get("status"), "reason": entry.get("reason", "")}
            continue
        seq = reader.read(name)
        with torch.no_grad():
            body = avatar.pose_motion(seq.motion).vertices.cpu().numpy()
        q = quality(seq.garment_vertices, reader.template, body, faces, seq.motion.fps)
        inside = np.asarray(q["inside_fraction"])  # (T,)
        flat = flatten_overlaps(body, parts, cloth["overlap_inset"])
        folded = flat.moved > 0  # (T,) frames whose pose folds into itself
        inside_flat = inside.copy()
        for t in np.nonzero(folded)[0]:
            inside_flat[t] = closest_points(
                flat.vertices[t], faces, seq.garment_vertices[t]
            ).inside.mean()
        rows[name] = {
            "frames": int(seq.motion.num_frames),
            "inside_mean_pct": 100 * q["inside_mean"],
            "inside_p99_pct": 100 * float(np.percentile(inside, 99)),
            # the part of inside_mean_pct in self-intersecting frames; against the collider
            "inside_folded_pct": 100 * float(inside[folded].sum() / len(inside)),
            "inside_collider_pct": 100 * float(inside_flat.mean()),
            "deep_max_pct": 100 * q["penetration_max"],
            "depth_max_cm": 100 * q["inside_depth_max"],
            "strain_p99": q["strain_p99"],
            "seconds_per_frame": entry.get("seconds_per_frame"),
            "overlap_frames": entry.get("overlap_frames"),
            "overlap_depth_cm": 100 * entry.get("overlap_depth_max", 0.0),
            "kept": bool(
                q["inside_depth_max"] <= limits.max_inside_depth
                and q["penetration_max"] <= limits.max_penetration_fraction
            ),
        }
    return rows


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
        results[variant] = judge(folder)
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
