"""The engine tier's waistband and its distance from the full pipeline, on the demo's dances
and the held-out clips, one command.

For each motion, the full pipeline (``animate``: PyTorch, every stage) and the engine tier
(:func:`~loosefit.inference.engine.model.rollout_engine` with the capsule push-out, as the
exported graph runs it) animate the same frames; per frame, the waist ring's radius (the
mean horizontal distance of the waistband's vertices from their centroid) of each, and over
the motion the RMSE of the engine tier against the full pipeline. ``--before`` adds the same
figures for another engine tier (the one shipped before), pushed out as it was (the
waistband too: ``waist_blend`` 0).

    OMP_NUM_THREADS=1 python bench/quality/engine_waist.py --data datasets/dance \\
        --before out/engine-before.pt --out docs/results/ENGINE_WAIST.md

Writes the Markdown table and the figures as JSON in bench/figures/.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np
import torch

import loosefit
from loosefit.api import pretrained_checkpoint
from loosefit.body.capsules import avatar_capsules
from loosefit.data.format import DatasetReader
from loosefit.inference.engine.export import EngineStep, skeleton_record
from loosefit.inference.engine.model import engine_path_of, load_engine, rollout_engine
from loosefit.motion.motions import load_motion

# the figures of a page docs/X.md as JSON: bench/figures/X.json
FIGURES = Path(__file__).resolve().parents[1] / "figures"


# the demo's moves: `loosefit demo` (dance:20, seed 0), the README's `animate("dance:4")`,
# the export's check (dance:12), and other seeds of the demo's `--seed`
DEMO = "dance:20@0,dance:4@0,dance:12@0,dance:8@1,dance:8@2,dance:8@3"
HELD_OUT = "05_02,05_10,05_12,chain_60_03_60_07_61_03_61_07"
BALLET = ("05_02", "05_10", "05_12")
HOLD = 0.01  # m: the waist ring's radius within this of the full pipeline's, every frame


def waist_radius(garments: np.ndarray, waist: np.ndarray) -> np.ndarray:
    """(T,) the waist ring's radius: the mean distance in XY of the waistband's vertices
    (W,) from their centroid, of garments (T, V, 3)."""
    ring = garments[:, waist]  # (T, W, 3)
    return np.linalg.norm((ring - ring.mean(1, keepdims=True))[..., :2], axis=-1).mean(1)


def engine_figures(engine, step, motion, full: np.ndarray, waist: np.ndarray) -> dict:
    """One tier against the full pipeline's garments (T, V, 3) on ``motion``."""
    x = rollout_engine(engine, motion, collide=step)
    r, rf = waist_radius(x, waist), waist_radius(full, waist)
    with torch.no_grad():
        rest = engine.tier.decode(engine.tier.rest[None]).cpu().numpy()  # (1, V, 3)
    return {
        "rest_gap_cm": float(100 * np.abs(r - waist_radius(rest, waist)[0]).max()),
        "rmse_cm": float(100 * np.sqrt(((x - full) ** 2).sum(-1).mean())),
        "sq_sum": float(((x - full) ** 2).sum(-1).mean(1).sum()),
        "waist_cm": [float(100 * r.min()), float(100 * r.max())],
        "waist_gap_cm": float(100 * np.abs(r - rf).max()),
        "waist_holds": bool(np.abs(r - rf).max() <= HOLD),
    }


def full_garments(model, motion, name: str, cache: str | None) -> np.ndarray:
    """(T, V, 3) the full pipeline's garments of ``motion``, from ``cache`` when there."""
    if cache is None:
        return model.animate(motion).vertices
    path = Path(cache) / (name.replace(", ", "_").replace(":", "-").replace(" ", "") + ".npy")
    if not path.is_file():
        path.parent.mkdir(parents=True, exist_ok=True)
        np.save(path, model.animate(motion).vertices)
    return np.load(path)


def motions(args, avatar, reader, fps):
    for spec in args.demo.split(","):
        move, seed = spec.split("@")
        yield f"{move}, seed {seed}", "demo", load_motion(move, avatar, fps=fps, seed=int(seed))
    for name in args.clips.split(","):
        yield name, "held out", reader.read(name).motion


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", default="datasets/dance")
    p.add_argument("--checkpoint", default=None, help="motion.pt (default: the pretrained)")
    p.add_argument("--engine", default=None, help="engine.pt (default: beside --checkpoint)")
    p.add_argument("--before", default=None, help="another engine.pt, pushed out as before")
    p.add_argument("--demo", default=DEMO, help="MOVE@SEED, comma-separated")
    p.add_argument("--clips", default=HELD_OUT)
    p.add_argument(
        "--cache",
        default=None,
        help="a folder for the full pipeline's garments (.npy per motion), reused "
        "when there: to measure another tier against the same",
    )
    p.add_argument("--out", default="docs/results/ENGINE_WAIST.md")
    p.add_argument("--machine", default=platform.node(), help="the machine's name in the doc")
    p.add_argument("--date", default=time.strftime("%Y-%m-%d"))
    args = p.parse_args()
    torch.set_num_threads(1)
    checkpoint = Path(args.checkpoint) if args.checkpoint else pretrained_checkpoint()
    model = loosefit.load(checkpoint).model
    avatar = model.avatar()
    capsules, skeleton = avatar_capsules(avatar), skeleton_record(avatar)
    tiers = {"engine tier": load_engine(args.engine or engine_path_of(checkpoint))}
    if args.before:
        tiers["before"] = load_engine(args.before)
    steps = {"engine tier": EngineStep(tiers["engine tier"], capsules, skeleton).eval()}
    if args.before:
        steps["before"] = EngineStep(tiers["before"], capsules, skeleton, waist_blend=0).eval()
    waist = model.template.waist
    reader = DatasetReader(args.data)
    result = {
        "machine": f"{args.machine}, {os.cpu_count()} CPUs, torch {torch.__version__}",
        "date": args.date,
        "checkpoint": str(checkpoint),
        "engines": {k: str(e.path) for k, e in tiers.items()},
        "motions": {},
    }
    for name, kind, motion in motions(args, avatar, reader, tiers["engine tier"].fps):
        full = full_garments(model, motion, name, args.cache)
        rf = waist_radius(full, waist)
        row = {
            "kind": kind,
            "frames": len(full),
            "full_waist_cm": [float(100 * rf.min()), float(100 * rf.max())],
        }
        for label, engine in tiers.items():
            row[label] = engine_figures(engine, steps[label], motion, full, waist)
        result["motions"][name] = row
        print(name, json.dumps(row), flush=True)
    summarise(result, list(tiers))
    out = Path(args.out)
    (FIGURES / f"{out.stem}.json").write_text(json.dumps(result, indent=1) + "\n")
    out.write_text(markdown(result, list(tiers)))
    print(out.read_text())


def summarise(result: dict, labels: list[str]) -> None:
    """The targets per tier: the ring within 1 cm everywhere; the demo's RMSE at most 1.5x
    the held-out ballet's (all of its frames pooled)."""
    rows = result["motions"]
    ballet = [rows[n] for n in BALLET if n in rows]
    result["targets"] = {}
    for label in labels:
        frames = sum(r["frames"] for r in ballet)
        pooled = 100 * np.sqrt(sum(r[label]["sq_sum"] for r in ballet) / max(frames, 1))
        demo = [r[label]["rmse_cm"] for r in rows.values() if r["kind"] == "demo"]
        result["targets"][label] = {
            "ballet_rmse_cm": float(pooled),
            "worst_demo_rmse_cm": float(max(demo)),
            "worst_ratio": float(max(demo) / pooled),
            "waist_holds_everywhere": all(r[label]["waist_holds"] for r in rows.values()),
        }


def markdown(r: dict, labels: list[str]) -> str:
    lines = [
        f"# The engine tier's waist against the full pipeline ({r['machine']}, {r['date']})",
        "",
        "Written by `OMP_NUM_THREADS=1 python bench/quality/engine_waist.py`. Waist ring: the mean "
        "horizontal distance of the waistband's vertices from their centroid, per frame "
        "(cm, least-greatest over the motion); gap: the largest difference from the full "
        "pipeline's in a frame; from rest: the largest difference from the settled drape's "
        "(the band as the simulation glues it); RMSE: against the full pipeline over the "
        "motion (cm).",
        "",
    ]
    head = "| motion | frames | full pipeline's waist |"
    rule = "|---|---:|---:|"
    for label in labels:
        head += f" {label}: waist | gap | from rest | RMSE |"
        rule += "---:|---:|---:|---:|"
    lines += [head, rule]
    for name, row in r["motions"].items():
        lo, hi = row["full_waist_cm"]
        cells = f"| {name} | {row['frames']} | {lo:.1f}-{hi:.1f} |"
        for label in labels:
            e = row[label]
            cells += (
                f" {e['waist_cm'][0]:.1f}-{e['waist_cm'][1]:.1f} | "
                f"{e['waist_gap_cm']:.2f} | {e['rest_gap_cm']:.2f} | "
                f"{e['rmse_cm']:.2f} |"
            )
        lines.append(cells)
    lines.append("")
    for label, t in r["targets"].items():
        lines.append(
            f"- {label}: waist ring within 1 cm of the full pipeline's in every frame: "
            f"{'yes' if t['waist_holds_everywhere'] else 'no'}; RMSE on the held-out ballet "
            f"(05_02, 05_10, 05_12 pooled) {t['ballet_rmse_cm']:.2f} cm, on the demo's "
            f"motions at most {t['worst_demo_rmse_cm']:.2f} cm: {t['worst_ratio']:.2f}x "
            f"(target: at most 1.5x)."
        )
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
