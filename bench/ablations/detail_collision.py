"""Detail enhancement and collision handling (paper 3.4, 3.5) on the held-out salsa chain.

Part A needs no simulation: the committed pair's rollouts of the held-out chain's
motion (60_03 + 60_07 + 61_03 + 61_07, chained as the ``salsa`` preset chains them)
and of the procedural spin, with each stage on or off, scored on what needs no
ground truth: vertices inside the body (the simulation's collider, winding number),
edge strain, the Laplacian change collision handling makes, and milliseconds per
frame of each stage. Part B (``--data``, ``--detail``, ``--detail-nodisc``) is
Table 2's form: RMSE, Hausdorff and STED against the simulation of every held-out
clip of ``--data`` (each its own table, and their mean weighted by frames) for no
module, the module without ``D_ms`` and the full module, each with and without
collision handling; ``--no-part-a`` leaves part A out::

    python bench/ablations/detail_collision.py --out docs/results/DETAIL_TABLE.md  # part A
    python bench/ablations/detail_collision.py --data datasets/salsa \\
        --detail runs/salsa/detail/full/model.pt \\
        --detail-nodisc runs/salsa/detail/nodisc/model.pt \\
        [--detail-edge runs/salsa/detail/full-edge/model.pt] --out docs/results/DETAIL_TABLE.md
    python bench/ablations/detail_collision.py --checkpoint checkpoints/dance/motion.pt \
        --data datasets/dance --detail runs/dance/ft/detail/model.pt \
        --detail-nodisc runs/dance/tables/detail-nodisc/model.pt --no-part-a \
        --out docs/results/DETAIL_DANCE_TABLE.md
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import torch

import loosefit
from loosefit.eval.metrics import hausdorff, inside_fraction, rmse_per_frame, sted
from loosefit.garment.quality import edge_strain
from loosefit.inference.animator import attach_detail
from loosefit.inference.stages import MOTION_ONLY, Stages
from loosefit.train.common import machine

# the figures of a page docs/X.md as JSON: bench/figures/X.json
FIGURES = Path(__file__).resolve().parents[1] / "figures"


ROWS = {  # label: stages
    "motion stage alone": MOTION_ONLY,
    "+ collision": Stages(detail=False, lengths=False),
    "+ collision, fed back": Stages(detail=False, lengths=False, feedback=True),
}
DETAIL_ROWS = {  # with a detail stage packaged beside the checkpoint
    "+ detail": Stages(lengths=False, collision=False),
    "+ detail + collision": Stages(lengths=False),
    "+ detail + collision, fed back": Stages(lengths=False, feedback=True),
}


def score(model, motion, vertices, body, collider) -> dict:
    """What needs no ground truth: inside the body, edge strain."""
    inside = 100 * inside_fraction(vertices, body, collider)
    strain, _ = edge_strain(vertices, model.template)
    return {
        "inside_mean_pct": float(inside.mean()),
        "inside_p99_pct": float(np.percentile(inside, 99)),
        "inside_max_pct": float(inside.max()),
        "strain_p50": float(np.median(strain)),
        "strain_p99": float(np.percentile(strain, 99)),
    }


def run(model, motion, stages: Stages, body, collider) -> dict:
    result = model.animate(motion, stages=stages)
    row = score(model, motion, result.vertices, body, collider)
    n = motion.num_frames
    row["ms_per_frame"] = {k: 1e3 * v / n for k, v in (result.stage_seconds or {}).items()}
    row["ms_per_frame_total"] = 1e3 * result.seconds / n
    if result.collisions:
        c = result.collisions
        row["laplacian_change_mm"] = 1e3 * float(np.mean([x["laplacian_change"] for x in c]))
        row["frames_with_cloth_inside_before"] = int(sum(x["inside_before"] > 0 for x in c))
        row["deepest_after_mm"] = 1e3 * float(max(x["depth_after"] for x in c))
    return row, result.vertices


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--checkpoint", default="checkpoints/salsa/motion.pt")
    p.add_argument(
        "--bvh", default=str(Path(__file__).resolve().parents[3] / "shared/mocap/cmu-salsa")
    )
    p.add_argument("--data", default=None, help="the salsa dataset (part B)")
    p.add_argument("--detail", default=None, help="the full detail module's model.pt (part B)")
    p.add_argument("--detail-nodisc", default=None, help="the module w/o D_ms (part B)")
    p.add_argument(
        "--detail-edge",
        default=None,
        help="the full module trained with the edge-length term (part B)",
    )
    p.add_argument("--no-part-a", action="store_true", help="Table 2 only (part B)")
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--out", default="docs/results/DETAIL_TABLE.md")
    args = p.parse_args()
    torch.set_num_threads(args.threads)

    from loosefit.motion.motions import load_motion
    from loosefit.sim.jobs import job_motion, plan_jobs
    from loosefit.sim.presets import preset

    model = loosefit.load(args.checkpoint).model  # with the detail stage packaged beside it, if any
    rows = dict(ROWS, **(DETAIL_ROWS if model.detail is not None else {}))
    avatar = model.avatar()
    collider = avatar.collider_faces(arms=model.arm_collision).cpu().numpy()
    results: dict = {"machine": machine("cpu"), "checkpoint": args.checkpoint, "part_a": {}}
    if args.no_part_a and not args.data:
        p.error("--no-part-a needs --data (part B)")
    if args.no_part_a:
        results["part_b"] = table2(args, model, collider)
        write(Path(args.out), results)
        return
    config = preset("salsa", args.bvh)
    chain = next(j for j in plan_jobs(config) if j.name.startswith("chain_"))
    motions = {
        chain.name: job_motion(config, chain, avatar),
        "spin": load_motion("spin", avatar, fps=model.fps),
    }
    model.animate(motions["spin"].slice(0, 10), stages=Stages())  # warm-up: kernels, caches
    for name, motion in motions.items():
        body = avatar.pose_motion(motion).vertices.cpu().numpy()
        results["part_a"][name] = {}
        for label, stages in rows.items():
            row, _ = run(model, motion, stages, body, collider)
            results["part_a"][name][label] = row
            print(name, label, json.dumps(row))

    if args.data:
        results["part_b"] = table2(args, model, collider)
    write(Path(args.out), results)


def write(out: Path, results: dict) -> None:
    """The table (Markdown) and its figures (JSON, in bench/figures/)."""
    (FIGURES / f"{out.stem}.json").write_text(json.dumps(results, indent=1))
    out.write_text(markdown(results))
    print(f"wrote {out} and {FIGURES / (out.stem + '.json')}")


def table2(args, model, collider) -> dict:
    """Table 2's rows against the simulation, per held-out clip: ``{clip: {row: figures}}``,
    and ``"all"``: each row's figures averaged over the clips, weighted by their frames
    (RMSE as the root of the mean square)."""
    from loosefit.data.format import DatasetReader

    reader = DatasetReader(args.data)
    variants = {
        "no module": None,
        "module w/o D_ms": args.detail_nodisc,
        "full module": args.detail,
        "full module + edge-length term": args.detail_edge,
    }
    clips: dict[str, dict] = {}
    avatar = model.avatar()
    for name in reader.split("test"):
        seq = reader.read(name)
        truth = seq.garment_vertices
        body = avatar.pose_motion(seq.motion).vertices.cpu().numpy()
        rows = clips[name] = {}
        for label, path in variants.items():
            if label != "no module" and path is None:
                continue
            model.detail = None
            if path is not None:
                attach_detail(model, path)
            for collision in (False, True):
                result = model.animate(seq.motion, stages=Stages(collision=collision))
                v = result.vertices
                per = 100 * rmse_per_frame(v, truth)
                row = {
                    "frames": int(len(v)),
                    "rmse_cm": float(np.sqrt(np.mean(per**2))),
                    "hausdorff_cm": 100 * float(hausdorff(v, truth, model.template.faces).mean()),
                    "sted": sted(v, truth, model.template.faces)["sted"],
                    **score(model, seq.motion, v, body, collider),
                }
                if result.collisions:
                    row["laplacian_change_mm"] = 1e3 * float(
                        np.mean([x["laplacian_change"] for x in result.collisions])
                    )
                rows[f"{label}{' + collision' if collision else ''}"] = row
                print(name, label, collision, json.dumps(row))
        rows["simulation"] = {
            "frames": int(len(truth)),
            **score(model, seq.motion, truth, body, collider),
        }
    clips["all"] = pooled(clips)
    return clips


def pooled(clips: dict[str, dict]) -> dict:
    """Each row's figures over all clips, weighted by frames; RMSE pooled as a mean square,
    the maxima as maxima."""
    out = {}
    for label in next(iter(clips.values())):
        rows = [c[label] for c in clips.values() if label in c]
        w = np.array([r["frames"] for r in rows], float)
        row = {"frames": int(w.sum())}
        for k in rows[0]:
            if k == "frames":
                continue
            x = np.array([r[k] for r in rows], float)
            if k == "rmse_cm":
                row[k] = float(np.sqrt(np.sum(w * x**2) / w.sum()))
            elif k.endswith("_max_pct"):
                row[k] = float(x.max())
            else:
                row[k] = float(np.sum(w * x) / w.sum())
        out[label] = row
    return out


def markdown(results: dict) -> str:
    lines = [
        "# Detail enhancement and collision handling on held-out motion",
        "",
        f"Machine: {results['machine']} (`bench/ablations/detail_collision.py`).",
        "",
    ]
    if results["part_a"]:
        lines += [
            "## Without ground truth: the committed pair, collision handling on and off",
            "",
            "| motion | stages | inside mean % | inside p99 % | inside max % | strain p50 | "
            "strain p99 | Laplacian change (mm) | ms/frame (motion / detail / collision) |",
            "|---|---|---:|---:|---:|---:|---:|---:|---|",
        ]
        for name, rows in results["part_a"].items():
            for label, r in rows.items():
                ms = r["ms_per_frame"]
                lines.append(
                    f"| {name} | {label} | {r['inside_mean_pct']:.4f} | "
                    f"{r['inside_p99_pct']:.2f} | {r['inside_max_pct']:.2f} | "
                    f"{r['strain_p50']:.3f} | {r['strain_p99']:.3f} | "
                    f"{r.get('laplacian_change_mm', 0.0):.2f} | {ms.get('motion', 0):.1f} / "
                    f"{ms.get('detail', 0):.1f} / {ms.get('collision', 0):.1f} |"
                )
    if "part_b" in results:
        for clip, rows in results["part_b"].items():
            title = (
                "all held-out clips (frame-weighted mean; inside max: the worst clip)"
                if clip == "all"
                else clip
            )
            lines += [
                "",
                f"## Table 2: against the simulation, {title}",
                "",
                "| row | RMSE (cm) | Hausdorff (cm) | STED | inside mean % | inside p99 % | "
                "strain p50 | strain p99 | Laplacian change (mm) |",
                "|---|---:|---:|---:|---:|---:|---:|---:|---:|",
            ]
            for label in sorted(rows, key=lambda k: k == "simulation"):  # the simulation last
                r = rows[label]
                cells = [
                    f"{r[k]:.3f}" if k in r else "-" for k in ("rmse_cm", "hausdorff_cm", "sted")
                ]
                lines.append(
                    f"| {label} | " + " | ".join(cells) + f" | "
                    f"{r['inside_mean_pct']:.4f} | {r['inside_p99_pct']:.2f} | "
                    f"{r['strain_p50']:.3f} | {r['strain_p99']:.3f} | "
                    + (f"{r['laplacian_change_mm']:.2f} |" if "laplacian_change_mm" in r else "- |")
                )
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
