"""Motion-stage candidates side by side, against the ensemble: what the validation clips
choose by, and what the held-out clips show.

Each candidate is a motion stage scored by ``bench/quality/ensemble.py --validation`` (its
JSON: the energy score on the validation clips, deterministic, and the held-out clips'
ensemble measures), optionally with ``bench/quality/knee_cover.py --json`` (raised-knee
frames the simulation covers and the candidate misses, on the validation clips) and its
run's ``config.json`` (the recipe, written into the table). Nothing is rolled out here:
the page gathers what those two scripts measured, so that every candidate tried for a
motion stage sits in one table with its recipe::

    OMP_NUM_THREADS=1 python bench/quality/ensemble.py --validation --baselines runs/none \\
        --checkpoint runs/dance/X/set/motion.pt --cache runs/dance/X/ensemble \\
        --out runs/dance/X/ENSEMBLE_X.md       # writes bench/figures/ENSEMBLE_X.json
    OMP_NUM_THREADS=1 python bench/quality/knee_cover.py --factors 3 \\
        --checkpoint runs/dance/X/set/motion.pt --json runs/dance/X/knee.json
    python bench/quality/motion_candidates.py \\
        --candidate "shipped=bench/figures/ENSEMBLE.json" --knee shipped=runs/shipped-knee.json \\
        --candidate "X=runs/dance/X/ENSEMBLE_X.json" --knee X=runs/dance/X/knee.json \\
        --config X=runs/dance/X/motion/config.json --out docs/results/MOTION_CANDIDATES.md

The first candidate is the reference the others are compared with. ``--keep`` adds the
candidates given to those the page's JSON already holds (their runs may be gone; each keeps
the date it was gathered), so that a new candidate joins the table without the old runs.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

FIGURES = Path(__file__).resolve().parents[1] / "figures"
MODEL = "ours-full"  # the deterministic garment through every stage, as ensemble.py names it
TERMS = ("membrane", "bending", "collision", "flare", "speed")


def pairs(values: list[str], what: str) -> dict[str, str]:
    """``LABEL=VALUE`` arguments to a dict, in order."""
    out = {}
    for v in values:
        label, eq, value = v.partition("=")
        if not (label and eq and value):
            raise SystemExit(f"--{what} takes LABEL=PATH, found {v!r}")
        out[label] = value
    return out


def recipe(config: dict) -> str:
    """A run's training configuration in words: epochs, start, learning rate, the loss's
    optional terms, the windows and the data."""
    t = config.get("train", config)
    loss = t.get("loss", {})
    terms = ", ".join(f"{k} {loss[k]:g}" for k in TERMS if loss.get(k))
    parts = [
        f"{t.get('epochs')} epochs"
        + (f" from `{t['init']}`" if t.get("init") else " from scratch")
        + f", lr {t.get('lr'):g}",
        f"terms: {terms or 'none'}",
    ]
    if t.get("unroll"):
        parts.append("unrolled windows")
    if t.get("mirror"):
        parts.append("mirrored clips")
    parts.append(f"generative `{config.get('generative', '?')}`")
    if config.get("dataset"):
        parts.append(f"data `{Path(config['dataset']).name}`")
    return "; ".join(parts)


def gather(candidates: dict, knees: dict, configs: dict) -> dict:
    """Each candidate's figures from its JSON files."""
    out = {}
    for label, path in candidates.items():
        e = json.loads(Path(path).read_text())
        if MODEL not in e.get("validation", {}):
            raise SystemExit(f"{path}: no validation score of {MODEL} (ensemble.py --validation)")
        row = {
            "ensemble": path,
            "machine": e.get("machine"),
            "validation_es_cm": e["validation"][MODEL]["energy_score_cm"],
            "validation_clips": e["validation"][MODEL]["clips"],
            "held_out": {
                clip: {
                    k: c["models"][MODEL][k]
                    for k in (
                        "energy_score_cm",
                        "rmse_to_mean_cm",
                        "rmse_members_ratio",
                        "flare_in_band",
                        "speed_in_band",
                        "sted_to_members",
                        "knee_missed",
                    )
                }
                for clip, c in e["clips"].items()
            },
        }
        if label in knees:
            k = json.loads(Path(knees[label]).read_text())
            row["knee"] = {"file": knees[label], "totals": k["totals"]}
        if label in configs:
            row["recipe"] = recipe(json.loads(Path(configs[label]).read_text()))
        out[label] = row
    return out


def knee_cell(row: dict, garment: str) -> str:
    t = row.get("knee", {}).get("totals", {})
    hit = [v for k, v in t.items() if k.startswith(garment)]
    return f"{hit[0]['missed']} of {hit[0]['simulation_covers']}" if hit else "-"


def markdown(rows: dict, started: str, command: str) -> str:
    """The page; ``command``: the stem of the JSON beside it in bench/figures."""
    labels = list(rows)
    ref = rows[labels[0]]
    clips = list(ref["held_out"])
    lines = [
        "# Motion-stage candidates against the ensemble",
        "",
        f"Gathered by `bench/quality/motion_candidates.py` ({started}; its calls and the date "
        f"each candidate was gathered (`--keep` keeps earlier ones) in "
        f"`bench/figures/{command}.json`) from each candidate's "
        "`bench/quality/ensemble.py --validation` figures (rolled out through every stage, "
        "deterministic: no realisations) and `bench/quality/knee_cover.py`. The validation "
        "clips choose (the energy score, lower is better); the held-out clips are shown, never "
        f"used to choose. Machine of the first: {ref['machine']}. A recipe names its training "
        "data where the run recorded it; a candidate gathered before that trained on `dance`.",
        "",
        "## Recipes and the validation clips",
        "",
        "| candidate | recipe | validation ES cm | against the first | raised knee missed, "
        "every stage | motion stage alone |",
        "|---|---|---:|---:|---:|---:|",
    ]
    es0 = ref["validation_es_cm"]
    for label, r in rows.items():
        es = r["validation_es_cm"]
        lines.append(
            f"| {label} | {r.get('recipe', '-')} | {es:.3f} | {100 * (es / es0 - 1):+.1f} % | "
            f"{knee_cell(r, 'every stage')} | {knee_cell(r, 'motion stage alone')} |"
        )
    lines += [
        "",
        "## The held-out clips",
        "",
        "Each cell: " + " / ".join(clips) + ".",
        "",
        "| candidate | ES cm | RMSE to the members / their spread | flare in band % "
        "| STED | STED against the first | knee frames missed |",
        "|---|---|---|---|---|---|---|",
    ]
    for label, r in rows.items():
        h = r["held_out"]

        def cells(key: str, fmt: str, h=h) -> str:
            return " / ".join(format(h[c][key], fmt) for c in clips)

        sted = " / ".join(
            f"{100 * (h[c]['sted_to_members'] / ref['held_out'][c]['sted_to_members'] - 1):+.0f} %"
            for c in clips
        )
        knee = " / ".join(str(len(h[c]["knee_missed"] or [])) for c in clips)
        flare = " / ".join(f"{100 * h[c]['flare_in_band']:.0f}" for c in clips)
        lines.append(
            f"| {label} | {cells('energy_score_cm', '.2f')} | "
            f"{cells('rmse_members_ratio', '.2f')} | {flare} | "
            f"{cells('sted_to_members', '.4f')} | {sted} | {knee} |"
        )
    lines.append("")
    return "\n".join(lines) + "\n"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--candidate", action="append", default=[], metavar="LABEL=ENSEMBLE_JSON")
    p.add_argument("--knee", action="append", default=[], metavar="LABEL=KNEE_JSON")
    p.add_argument("--config", action="append", default=[], metavar="LABEL=CONFIG_JSON")
    p.add_argument("--out", default="docs/results/MOTION_CANDIDATES.md")
    p.add_argument(
        "--keep",
        action="store_true",
        help="also keep the candidates the page's figures (bench/figures/) already hold, "
        "gathered earlier (their runs may be gone); a --candidate of the same label replaces one",
    )
    args = p.parse_args()
    candidates = pairs(args.candidate, "candidate")
    if not candidates and not args.keep:
        raise SystemExit("name at least one --candidate LABEL=ENSEMBLE_JSON")
    knees, configs = pairs(args.knee, "knee"), pairs(args.config, "config")
    for what, given in (("--knee", knees), ("--config", configs)):
        stray = set(given) - set(candidates)
        if stray:
            raise SystemExit(f"{what} names no --candidate: {', '.join(sorted(stray))}")
    started = time.strftime("%Y-%m-%d")
    out = Path(args.out)
    command = out.stem
    rows, calls = {}, []
    if args.keep:  # the earlier candidates first, in their order (the first: the reference)
        before = json.loads((FIGURES / f"{out.stem}.json").read_text())
        rows, calls = before["candidates"], before["calls"]
    for label, row in gather(candidates, knees, configs).items():
        rows[label] = {"gathered": started} | row
    calls.append({"gathered": started, "arguments": vars(args)})
    (FIGURES / f"{out.stem}.json").write_text(
        json.dumps({"calls": calls, "candidates": rows}, indent=1) + "\n"
    )
    out.write_text(markdown(rows, started, command))
    print(out.read_text())


if __name__ == "__main__":
    main()
