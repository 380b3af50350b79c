"""An account of every stage: where the learned skirt stops being cloth.

For each simulated clip given (a data set folder, every clip of it or those named, or a
sequence ``.npz`` with its motion), the committed model's stages are run on the clip's
motion and measured against the simulation:

* ``simulation``: the ground truth itself;
* ``oracle``: the generative model's own reconstruction of the truth (encode, decode);
* ``oracle + lengths``: that, with the edge-length stage (stages.lengths.LengthRestorer);
* ``motion stage``: the rollout's decoded garment;
* ``+ detail``: with the detail stage (paper 3.4);
* ``today``: + collision handling as it was before the arms joined it (the arms out of the
  collider, no last projection);
* ``+ lengths``: + detail + the edge-length stage;
* ``+ lengths, all edges``: the same restoring every edge, not only the hanging ones;
* ``after``: the whole pipeline now (detail, edge lengths, collision handling against the
  whole body with the last projection).

Measures (per clip and stage): edge strain ``|l/L - 1|`` median and p99 and the median
signed edge change (the waistband's own edges left out); bending: the mean absolute dihedral
angle and the 1-Wasserstein distance of the dihedral angles from the simulation's; hem flare
(the hem's mean horizontal distance from the pelvis's vertical axis): its mean over the clip
and, over the 61 frames around the clip's fastest turn, the mean of ``|flare / flare_sim - 1|``
frame by frame; cloth inside the body, whole body (arms and hands included) and the
simulation's collider (arms cut away): the mean share of vertices per frame, the frames with
a vertex deeper than 5 mm and the deepest; RMSE, Hausdorff and STED against the simulation.

    .venv/bin/python bench/quality/stage_account.py --data datasets/account \\
        [--sequence out/chain_spin.npz] [--checkpoint checkpoints/salsa/motion.pt] \\
        [--out docs/results/STAGE_ACCOUNT.md]

Writes the table (markdown), the figures as JSON in bench/figures/, and a plot of the hem flare
per frame around each clip's fastest turn (``docs/img/stage_account_flare.png``).
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
from loosefit.train.common import machine

# the figures of a page docs/X.md as JSON: bench/figures/X.json
FIGURES = Path(__file__).resolve().parents[1] / "figures"


COLUMNS = [  # key, header, format
    ("strain_p50", "strain p50", "{:.3f}"),
    ("strain_p99", "strain p99", "{:.3f}"),
    ("edge_change_p50", "edge change p50 %", "{:+.1%}"),
    ("dihedral_w1", "dihedral W1 (rad)", "{:.3f}"),
    ("flare_mean_m", "flare cm", "{:.1f}"),
    ("flare_turn_error", "flare error at turn", "{:.1%}"),
    ("inside_whole_mean", "inside whole body %", "{:.3%}"),
    ("deep_whole_frames", "frames > 5 mm (whole)", "{}"),
    ("deepest_whole_m", "deepest cm (whole)", "{:.2f}"),
    ("inside_collider_mean", "inside collider %", "{:.3%}"),
    ("rmse_cm", "RMSE cm", "{:.2f}"),
    ("hausdorff_cm", "Hausdorff cm", "{:.2f}"),
    ("sted", "STED", "{:.4f}"),
]


def cell(key: str, fmt: str, value) -> str:
    if key == "flare_mean_m" or key == "deepest_whole_m":
        value = 100 * value
    if fmt.endswith("%}"):
        return fmt.format(value).replace("%", "")
    return fmt.format(value)


def table(clips: dict) -> str:
    lines = []
    for name, c in clips.items():
        lines.append(
            f"\n### {name} ({c['frames']} frames, fastest turn at frame {c['turn_frame']})\n"
        )
        lines.append("| stage | " + " | ".join(h for _, h, _ in COLUMNS) + " |")
        lines.append("|---|" + "---:|" * len(COLUMNS))
        for label, r in c["rows"].items():
            lines.append(
                f"| {label} | " + " | ".join(cell(k, f, r[k]) for k, _, f in COLUMNS) + " |"
            )
    return "\n".join(lines)


def plot(clips: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(clips), figsize=(4.5 * len(clips), 3.4), squeeze=False)
    for ax, (name, c) in zip(axes[0], clips.items(), strict=True):
        t = np.arange(*c["window"])
        for label in ("simulation", "oracle", "motion stage", "today", "after"):
            ax.plot(t, 100 * np.asarray(c["rows"][label]["flare_turn"]), label=label)
        ax.set_title(name, fontsize=9)
        ax.set_xlabel("frame")
        ax.set_ylabel("hem flare (cm)")
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--checkpoint", default="checkpoints/salsa/motion.pt")
    p.add_argument(
        "--before",
        default=None,
        help="the pipeline of the 'today' row (default: --checkpoint's), e.g. the "
        "set before the physics terms in out/salsa-without-physics-terms/motion.pt",
    )
    p.add_argument(
        "--data",
        nargs="*",
        default=["datasets/account"],
        help="data set folders (every clip, or --clips)",
    )
    p.add_argument("--clips", nargs="*", default=None, help="only these clips")
    p.add_argument("--sequence", nargs="*", default=[], help="simulated sequence .npz files")
    p.add_argument("--max-frames", type=int, default=None)
    p.add_argument("--out", default="docs/results/STAGE_ACCOUNT.md")
    p.add_argument("--plot", default="docs/img/stage_account_flare.png")
    args = p.parse_args()

    from loosefit.data.format import DatasetReader, read_any_sequence

    torch.set_num_threads(1)
    model = loosefit.load(args.checkpoint).model
    before = loosefit.load(args.before).model if args.before else None
    sources = {}
    for folder in args.data:
        reader = DatasetReader(folder, allow_incomplete=True)
        done = sorted(f.stem for f in (Path(folder) / "sequences").glob("*.npz"))
        for name in done:  # the finished clips (a data set still simulating lists none)
            if args.clips is None or name in args.clips:
                sources[name] = (reader, name)
    for f in args.sequence:
        sources[Path(f).stem] = (None, f)
    clips = {}
    for name, (reader, what) in sources.items():
        seq = reader.read(what) if reader is not None else read_any_sequence(what)
        if args.max_frames:
            seq = replace(
                seq,
                motion=seq.motion.slice(0, args.max_frames),
                garment_vertices=seq.garment_vertices[: args.max_frames],
            )
        print(f"{name}: {seq.motion.num_frames} frames", flush=True)
        clips[name] = clip_account(model, name, seq, before=before)
    out = Path(args.out)
    record = {
        "checkpoint": str(Path(args.checkpoint).resolve()),
        "before": str(Path(args.before).resolve()) if args.before else None,
        "machine": machine("cpu"),
        "platform": platform.platform(),
        "torch": torch.__version__,
        "threads": 1,
        "cpus": os.cpu_count(),
        "clips": clips,
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    (FIGURES / f"{out.stem}.json").write_text(json.dumps(record, indent=1))
    plot(clips, Path(args.plot))
    body = table(clips)
    print(body)
    marker = "<!-- stage account table -->"
    if out.is_file() and marker in out.read_text():
        head = out.read_text().split(marker)[0]
        out.write_text(head + marker + "\n" + body + "\n")
    else:
        out.write_text(f"# The stage account\n\n{marker}\n{body}\n")
    print(f"wrote {out}, {FIGURES / (out.stem + '.json')} and {args.plot}")


if __name__ == "__main__":
    main()
