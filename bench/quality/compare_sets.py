"""Which trained set to ship: candidate sets compared on clips none of them trained on.

Each candidate (a packaged set's ``motion.pt``, its ``detail.pt`` beside it) animates every
clip given, the whole pipeline (motion stage, detail, edge lengths, collision handling),
from the clip's first frame on its own motion, and is measured against the simulation with
the stage account's figures (``bench/quality/stage_account.py``: RMSE, Hausdorff, STED, edge strain
and signed edge change, hem flare around the fastest turn, cloth inside the whole body).

The choice is made on a **validation** set that is neither trained on nor held out: a data
set's clips that its split leaves out (``dance``: the clips the simulator flagged, whose
simulations are kept for study; the ones that exploded, edge strain p99 over 1, are left out
here too). The held-out clips are scored as well, for the record, and never decide::

    python bench/quality/compare_sets.py --data datasets/dance \\
        --sets salsa=checkpoints/salsa/motion.pt fine-tuned=out/sets/ft/motion.pt \\
        --out docs/results/DANCE_SETS.md

Rollouts and figures are cached per set and clip in ``--cache`` (a killed run goes on).
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

import loosefit
from loosefit.data.format import DatasetReader
from loosefit.eval.heldout import validation_clips
from loosefit.eval.stage_account import clip_reference
from loosefit.train.common import machine

# the figures of a page docs/X.md as JSON: bench/figures/X.json
FIGURES = Path(__file__).resolve().parents[1] / "figures"


COLUMNS = [  # key, header, format, scale
    ("rmse_cm", "RMSE cm", "{:.2f}", 1),
    ("hausdorff_cm", "Hausdorff cm", "{:.2f}", 1),
    ("sted", "STED", "{:.4f}", 1),
    ("edge_change_p50", "edge change p50 %", "{:+.1f}", 100),
    ("strain_p50", "strain p50", "{:.3f}", 1),
    ("flare_turn_error", "flare error at turn %", "{:.1f}", 100),
    ("inside_whole_mean", "inside whole body %", "{:.3f}", 100),
    ("deep_whole_frames", "frames > 5 mm", "{:.0f}", 1),
]


def _cached(path: Path, make) -> dict:
    """``make()``'s figures, written to ``path`` atomically, or read back from it."""
    if path.is_file():
        return json.loads(path.read_text())
    out = make()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.stem + ".partial.json")
    tmp.write_text(json.dumps(out))
    tmp.replace(path)
    return out


def clip_figures(models: dict, seq, cache: Path, clip: str) -> dict[str, dict]:
    """Every set on one clip: its figures, each cached in ``cache/SET/CLIP.json``. The clip's
    reference (the posed body, the simulation's own figures) is made once for all the sets
    that share a collider (the same garment on the same avatar, the arms in or out), and
    only when a set's figures are not cached yet."""
    references: dict[str, dict] = {}

    def reference(model) -> dict:
        arms = str(model.arm_collision)
        if arms not in references:
            measure, turn, _ = clip_reference(model, seq)
            truth = _cached(
                cache / "simulation" / f"{clip}-arms-{arms}.json",
                lambda: {
                    k: v
                    for k, v in measure(np.asarray(seq.garment_vertices)).items()
                    if k != "flare_turn"
                },
            )
            references[arms] = {"measure": measure, "turn": turn, "truth": truth}
        return references[arms]

    def one(model) -> dict:
        t0 = time.perf_counter()
        x = model.animate(seq.motion).vertices
        seconds = time.perf_counter() - t0
        ref = reference(model)
        row = {k: v for k, v in ref["measure"](x).items() if k != "flare_turn"}
        return {
            "frames": seq.motion.num_frames,
            "seconds": seconds,
            "turn": ref["turn"],
            "row": row,
            "simulation": ref["truth"],
        }

    return {
        name: _cached(cache / name / f"{clip}.json", lambda m=model: one(m))
        for name, model in models.items()
    }


def pooled(figures: list[dict]) -> dict:
    """A group of clips: RMSE pooled over frames, the rest weighted by frames (frames > 5 mm
    summed)."""
    frames = np.array([f["frames"] for f in figures], float)
    out = {}
    for key, *_ in COLUMNS:
        values = np.array([f["row"][key] for f in figures], float)
        if key == "rmse_cm":
            out[key] = float(np.sqrt(np.average(values**2, weights=frames)))
        elif key == "deep_whole_frames":
            out[key] = float(values.sum())
        else:
            out[key] = float(np.average(values, weights=frames))
    return out


def table(groups: dict, sets: list[str]) -> list[str]:
    lines = [
        "| set | clips | " + " | ".join(h for _, h, *_ in COLUMNS) + " |",
        "|---|---|" + "---:|" * len(COLUMNS),
    ]
    for group, per_set in groups.items():
        for name in sets:
            p = pooled(per_set[name])
            cells = [fmt.format(scale * p[k]) for k, _, fmt, scale in COLUMNS]
            lines.append(f"| {name} | {group} | " + " | ".join(cells) + " |")
    return lines


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", default="datasets/dance")
    p.add_argument("--sets", nargs="+", required=True, help="NAME=path/to/motion.pt ...")
    p.add_argument("--cache", default="runs/dance/compare_sets")
    p.add_argument("--out", default="docs/results/DANCE_SETS.md")
    p.add_argument("--threads", type=int, default=1)
    p.add_argument(
        "--max-frames",
        type=int,
        default=None,
        help="each clip's first frames only (a quick look; the choice is made on whole clips)",
    )
    args = p.parse_args()
    torch.set_num_threads(args.threads)
    reader = DatasetReader(args.data)
    sets = dict(s.split("=", 1) for s in args.sets)
    groups = {"validation": validation_clips(reader), "held-out": reader.split("test")}
    figures: dict[str, dict[str, list[dict]]] = {g: {n: [] for n in sets} for g in groups}
    per_clip: dict[str, dict[str, dict]] = {}
    models = {name: loosefit.load(ckpt).model for name, ckpt in sets.items()}
    for group, clips in groups.items():
        for clip in clips:
            seq = reader.read(clip)
            if args.max_frames:
                n = args.max_frames
                seq = replace(
                    seq, motion=seq.motion.slice(0, n), garment_vertices=seq.garment_vertices[:n]
                )
            for name, f in clip_figures(models, seq, Path(args.cache), clip).items():
                figures[group][name].append(f)
                per_clip.setdefault(clip, {})[name] = f
                print(
                    f"{name} {group} {clip}: RMSE {f['row']['rmse_cm']:.2f} cm, edge change "
                    f"{100 * f['row']['edge_change_p50']:+.1f} %, flare error "
                    f"{100 * f['row']['flare_turn_error']:.1f} %",
                    flush=True,
                )
    val = {n: pooled(figures["validation"][n])["rmse_cm"] for n in sets}
    winner = min(val, key=val.get)
    lines = [
        "# Which set ships: the candidates on clips none trained on",
        "",
        f"Made by `bench/quality/compare_sets.py --data {args.data}` ({machine('cpu')}, "
        f"{time.strftime('%Y-%m-%d', time.gmtime())}); the whole pipeline, each clip rolled "
        "out from its first frame. **Validation** (decides): "
        + ", ".join(f"`{c}`" for c in groups["validation"])
        + " (clips the split leaves out: the simulator flagged them for cloth deeper than "
        "5 mm in the body in some frames; trained on by no set). **Held-out** (the record, "
        "never decides): " + ", ".join(f"`{c}`" for c in groups["held-out"]) + ".",
        "",
        "Sets: " + "; ".join(f"`{n}` = `{c}`" for n, c in sets.items()) + " (how each was "
        "trained: `scripts/dance_models.sh`, whose `set` step runs this).",
        "",
        *table(figures, list(sets)),
        "",
        f"**Chosen: `{winner}`**, the lowest validation RMSE ("
        + ", ".join(f"{n} {v:.2f} cm" for n, v in val.items())
        + ").",
        "",
        "RMSE per clip (cm):",
        "",
        "| clip | frames | " + " | ".join(sets) + " |",
        "|---|---:|" + "---:|" * len(sets),
    ]
    for clip, by_set in per_clip.items():
        frames = next(iter(by_set.values()))["frames"]
        cells = " | ".join(f"{by_set[n]['row']['rmse_cm']:.2f}" for n in sets)
        lines.append(f"| {clip} | {frames} | {cells} |")
    out = Path(args.out)
    out.write_text("\n".join(lines) + "\n")
    (FIGURES / f"{out.stem}.json").write_text(
        json.dumps(
            {
                "sets": sets,
                "groups": groups,
                "winner": winner,
                "validation_rmse_cm": val,
                "per_clip": per_clip,
            },
            indent=1,
        )
    )
    print(f"chosen: {winner}; wrote {out}")


if __name__ == "__main__":
    main()
