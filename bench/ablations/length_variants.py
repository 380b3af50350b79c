"""The edge-length stage restoring every edge, not only the hanging ones (the strain it leaves).

The committed pipeline restores the hanging edges of the garment after detail
(``LengthConfig(edges="hanging")``): the skirt gets its length back, but its circumferential
edges stay 7-9 % short and the edge strain p99 stays about 0.4 (the simulation's 0.05-0.09).
Restoring every edge (``edges="all"``) with the default tie turns that lost width into a bell
(docs/results/STAGE_ACCOUNT.md). This measures, on the account's clips, the stage with every edge
and a stronger tie to the network's shape (``tie``), before and after collision handling:
strain, edge change, flare at the fastest turn, inside the whole body, RMSE.

    .venv/bin/python bench/ablations/length_variants.py [--data datasets/account] \\
        [--sequence out/chain_spin.npz] [--out docs/design/notes/LENGTH_VARIANTS.md]

Writes the table (markdown) and the figures as JSON in bench/figures/. About 15 minutes on dev-cpu.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
from pathlib import Path

import numpy as np
import torch

import loosefit
from loosefit.eval.stage_account import clip_reference
from loosefit.inference.stages import Stages
from loosefit.inference.stages.lengths import LengthConfig
from loosefit.train.common import machine

# the figures of a page docs/X.md as JSON: bench/figures/X.json
FIGURES = Path(__file__).resolve().parents[1] / "figures"


VARIANTS = {  # label: the edge-length stage (None: as committed)
    "hanging edges (committed)": None,
    "all edges, tie 1e-3": LengthConfig(edges="all"),
    "all edges, tie 1e-2": LengthConfig(edges="all", tie=1.0e-2),
    "all edges, tie 3e-2": LengthConfig(edges="all", tie=3.0e-2),
}
KEYS = (
    "strain_p50",
    "strain_p99",
    "edge_change_p50",
    "flare_turn_error",
    "inside_whole_mean",
    "deep_whole_frames",
    "rmse_cm",
)


def clip_variants(model, name: str, seq) -> dict:
    """Every variant of :data:`VARIANTS` on one simulated clip, before and after collision."""
    motion, truth = seq.motion, np.asarray(seq.garment_vertices, np.float32)
    measure_garment, _, _ = clip_reference(model, seq)
    detail = model.animate(motion, stages=Stages(lengths=False, collision=False)).vertices
    rows = {}
    for label, lengths in VARIANTS.items():
        with model.configured(lengths=lengths):
            pre = model.restorer(Stages())(torch.from_numpy(detail)).numpy()
            collide = model.collider(motion)
            post = np.stack(
                [collide(t, torch.from_numpy(pre[t])).vertices.numpy() for t in range(len(pre))]
            )
        for when, x in (("before collision", pre), ("after collision", post)):
            r = measure_garment(x)
            rows[f"{label}, {when}"] = {k: r[k] for k in KEYS}
            print(
                f"  {name} {label}, {when}: strain p99 {r['strain_p99']:.3f}, edge change "
                f"{100 * r['edge_change_p50']:+.1f} %, flare error "
                f"{100 * r['flare_turn_error']:.1f} %, RMSE {r['rmse_cm']:.2f} cm",
                flush=True,
            )
    sim = measure_garment(truth)
    return {"frames": motion.num_frames, "simulation": {k: sim[k] for k in KEYS}, "rows": rows}


def table(clips: dict) -> str:
    head = (
        "| clip | variant | strain p50 | strain p99 | edge change % | flare error at turn % "
        "| inside whole body % | frames > 5 mm | RMSE cm |"
    )
    lines = [head, "|---|---|" + "---:|" * 7]

    def row(clip, label, r):
        return (
            f"| {clip} | {label} | {r['strain_p50']:.3f} | {r['strain_p99']:.3f} | "
            f"{100 * r['edge_change_p50']:+.1f} | {100 * r['flare_turn_error']:.1f} | "
            f"{100 * r['inside_whole_mean']:.3f} | {r['deep_whole_frames']} | "
            f"{r['rmse_cm']:.2f} |"
        )

    for name, c in clips.items():
        lines.append(row(name, "simulation", c["simulation"]))
        lines.extend(row(name, label, r) for label, r in c["rows"].items())
    return "\n".join(lines)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--checkpoint", default="checkpoints/salsa/motion.pt")
    p.add_argument("--data", default="datasets/account")
    p.add_argument("--sequence", nargs="*", default=["out/chain_spin.npz"])
    p.add_argument("--out", default="docs/design/notes/LENGTH_VARIANTS.md")
    args = p.parse_args()

    from loosefit.data.format import DatasetReader, read_any_sequence

    torch.set_num_threads(1)
    model = loosefit.load(args.checkpoint).model
    reader = DatasetReader(args.data, allow_incomplete=True)
    sources = {
        f.stem: reader.read(f.stem) for f in sorted((Path(args.data) / "sequences").glob("*.npz"))
    }
    sources.update({Path(f).stem: read_any_sequence(f) for f in args.sequence})
    clips = {}
    for name, seq in sources.items():
        print(f"{name}: {seq.motion.num_frames} frames", flush=True)
        clips[name] = clip_variants(model, name, seq)
    out = Path(args.out)
    record = {
        "checkpoint": str(Path(args.checkpoint).resolve()),
        "machine": machine("cpu"),
        "platform": platform.platform(),
        "torch": torch.__version__,
        "threads": 1,
        "cpus": os.cpu_count(),
        "clips": clips,
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    (FIGURES / f"{out.stem}.json").write_text(json.dumps(record, indent=1))
    body = table(clips)
    print(body)
    marker = "<!-- length variants table -->"
    if out.is_file() and marker in out.read_text():
        out.write_text(out.read_text().split(marker)[0] + marker + "\n" + body + "\n")
    else:
        out.write_text(f"# The edge-length stage on every edge\n\n{marker}\n{body}\n")
    print(f"wrote {out} and {FIGURES / (out.stem + '.json')}")


if __name__ == "__main__":
    main()
