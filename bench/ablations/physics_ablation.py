"""The ablation of the physics training terms: what each makes of the learned skirt.

Generative runs (``NAME=checkpoint.pt``, fine-tuned with and without the membrane, bending
and collision terms) are measured by their own reconstruction of the simulation (the
``oracle`` row of :mod:`bench.stage_account`); motion runs (``NAME=model.pt``, with and
without the membrane, bending and flare terms) by the motion stage alone and by the whole
pipeline after it (``after``: edge lengths and collision handling; a motion run has no
detail stage of its own). Every row on the account's clips (the procedural spin, three
held-out ballet clips, the held-out salsa chain's fastest spin), and each run's own report
on its data set's test split beside it (for the salsa data, the held-out chain of 1,957
frames).

    .venv/bin/python bench/ablations/physics_ablation.py \\
        --generative g-plain=runs/physics/g-plain/checkpoint.pt g-m=... \\
        --motion m-plain=runs/physics/m-plain/model.pt ... \\
        --data datasets/account --sequence out/chain_spin.npz --out docs/results/PHYSICS_ABLATION.md

Writes a table of the means over the clips (markdown) and every clip's figures as JSON.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

import loosefit
from loosefit.eval.stage_account import clip_account
from loosefit.inference.checkpoints import load_generative
from loosefit.train.common import machine

# the figures of a page docs/X.md as JSON: bench/figures/X.json
FIGURES = Path(__file__).resolve().parents[1] / "figures"


COLUMNS = [  # key, header, format (means over the clips)
    ("strain_p50", "strain p50", "{:.3f}"),
    ("strain_p99", "strain p99", "{:.3f}"),
    ("edge_change_p50", "edge change p50", "{:+.1%}"),
    ("dihedral_w1", "dihedral W1 (rad)", "{:.3f}"),
    ("flare_turn_error", "flare error at turn", "{:.1%}"),
    ("inside_whole_mean", "inside whole body", "{:.3%}"),
    ("deep_whole_frames", "frames > 5 mm", "{:.1f}"),
    ("rmse_cm", "RMSE cm", "{:.2f}"),
    ("hausdorff_cm", "Hausdorff cm", "{:.2f}"),
    ("sted", "STED", "{:.4f}"),
]


def named(items: list[str], flag: str) -> dict[str, Path]:
    out = {}
    for item in items:
        name, sep, path = item.partition("=")
        if not sep or not name or not path:
            raise SystemExit(f"{flag}: expected NAME=PATH, found {item!r}")
        if not Path(path).is_file():
            raise SystemExit(f"{flag}: {path} (run {name!r}) does not exist")
        out[name] = Path(path)
    return out


def run_report(path: Path) -> dict:
    """The held-out figures a run's own report gives (``report.json`` beside it)."""
    report = path.parent / "report.json"
    if not report.is_file():
        return {}
    r = json.loads(report.read_text())
    held = r.get("test") or r.get("held_out") or {}
    return {k: held[k] for k in ("rmse_cm", "hausdorff_cm", "sted") if k in held}


def means(clips: dict, label: str) -> dict:
    keys = [k for k, _, _ in COLUMNS]
    return {k: float(np.mean([c["rows"][label][k] for c in clips.values()])) for k in keys}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--base",
        default="checkpoints/salsa/motion.pt",
        help="the pipeline the generative runs' oracle rows are taken with",
    )
    p.add_argument("--generative", nargs="*", default=[], help="NAME=checkpoint.pt")
    p.add_argument("--motion", nargs="*", default=[], help="NAME=model.pt")
    p.add_argument("--data", nargs="*", default=["datasets/account"])
    p.add_argument("--sequence", nargs="*", default=["out/chain_spin.npz"])
    p.add_argument("--max-frames", type=int, default=None)
    p.add_argument("--out", default="docs/results/PHYSICS_ABLATION.md")
    args = p.parse_args()

    from loosefit.data.format import DatasetReader, read_any_sequence

    torch.set_num_threads(1)
    seqs = {}
    for folder in args.data:
        reader = DatasetReader(folder)
        for name in sorted(reader.manifest["sequences"]):
            seqs[name] = reader.read(name)
    for f in args.sequence:
        seqs[Path(f).stem] = read_any_sequence(f)
    if args.max_frames:
        seqs = {
            n: replace(
                s,
                motion=s.motion.slice(0, args.max_frames),
                garment_vertices=s.garment_vertices[: args.max_frames],
            )
            for n, s in seqs.items()
        }

    runs = {}  # name: (stage, rows, model)
    base = loosefit.load(args.base).model
    for name, path in named(args.generative, "--generative").items():
        gen, data = load_generative(path, base.template)
        model = replace(base, generative=gen, physics_terms=tuple(data.get("physics_terms", ())))
        runs[name] = ("generative", ("oracle",), model, path)
    for name, path in named(args.motion, "--motion").items():
        runs[name] = ("motion", ("motion stage", "after"), loosefit.load(path).model, path)

    record = {
        "machine": machine("cpu"),
        "platform": platform.platform(),
        "cpus": os.cpu_count(),
        "threads": 1,
        "runs": {},
    }
    lines = [
        "| run | stage | rows | "
        + " | ".join(h for _, h, _ in COLUMNS)
        + " | the run's own test split: RMSE / Hausdorff / STED |",
        "|---|---|---|" + "---:|" * len(COLUMNS) + "---|",
    ]
    for name, (stage, labels, model, path) in runs.items():
        clips = {}
        for clip, seq in seqs.items():
            print(f"{name}: {clip}", flush=True)
            clips[clip] = clip_account(model, clip, seq, labels)
        own = run_report(path)
        record["runs"][name] = {
            "path": str(path),
            "stage": stage,
            "clips": clips,
            "report": own,
            "physics_terms": list(model.physics_terms),
        }
        for label in labels:
            m = means(clips, label)
            record["runs"][name].setdefault("means", {})[label] = m
            held = (
                " / ".join(
                    f"{own[k]:.{d}f}"
                    for k, d in (("rmse_cm", 2), ("hausdorff_cm", 2), ("sted", 4))
                    if k in own
                )
                or "-"
            )
            lines.append(
                f"| {name} | {stage} | {label} | "
                + " | ".join(f.format(m[k]) for k, _, f in COLUMNS)
                + f" | {held} |"
            )
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    (FIGURES / f"{out.stem}.json").write_text(json.dumps(record, indent=1))
    body = "\n".join(lines)
    marker = "<!-- ablation table -->"
    if out.is_file() and marker in out.read_text():
        out.write_text(out.read_text().split(marker)[0] + marker + "\n" + body + "\n")
    else:
        out.write_text(f"# The physics terms, ablated\n\n{marker}\n{body}\n")
    print(body)
    print(f"wrote {out} and {FIGURES / (out.stem + '.json')}")


if __name__ == "__main__":
    main()
