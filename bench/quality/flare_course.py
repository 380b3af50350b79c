"""docs/results/FLARE_COURSE.md: how near each candidate's hem follows the members through
each held-out clip's fastest turn.

The ensemble's flare target counts the frames of the turn where the hem's flare lies inside
the members' range, yes or no; where the members agree to a centimetre, a hem that follows
their course a centimetre off scores as badly as one that never flares. This page reads the
flare series ``bench/quality/ensemble.py`` stored in each candidate's JSON (nothing is
rolled out) and gives, over the 61 frames of the turn: the flare over the members' mean and
the share inside their range (as ``ensemble.py`` scored them), how far outside it the hem
lies on average and at most (:func:`loosefit.eval.ensemble.band_gap`), and the RMS distance
from the members' mean flare::

    python bench/quality/flare_course.py --candidate shipped=bench/figures/ENSEMBLE.json \\
        --candidate X=runs/dance/X/ENSEMBLE_X.json --out docs/results/FLARE_COURSE.md
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from loosefit.eval.ensemble import band_gap

MODEL = "ours-full"  # the deterministic garment through every stage, as ensemble.py names it


def course(own: dict, members: dict) -> dict[str, float]:
    """A model's scores on one clip (``ensemble.py``'s, with its hem flare series (T,)
    ``flare_turn_m``) against the members' (their series (M, T)), in the page's measures."""
    x = np.asarray(own["flare_turn_m"], np.float64)
    band = np.asarray(members["flare_turn_m"], np.float64)
    gap = band_gap(x, band)
    return {
        "ratio": own["flare_turn_ratio"],
        "in_band": own["flare_in_band"],
        "gap_cm": 100 * float(gap.mean()),
        "max_gap_cm": 100 * float(gap.max()),
        "rms_cm": 100 * float(np.sqrt(((x - band.mean(0)) ** 2).mean())),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--candidate", action="append", default=[], metavar="LABEL=ENSEMBLE_JSON")
    p.add_argument("--out", default="docs/results/FLARE_COURSE.md")
    args = p.parse_args()
    if not args.candidate:
        p.error("--candidate LABEL=ENSEMBLE_JSON: at least one")
    rows: dict[str, dict[str, dict[str, float]]] = {}
    paths: dict[str, str] = {}
    for item in args.candidate:
        label, sep, path = item.partition("=")
        if not sep:
            p.error(f"--candidate: expected LABEL=ENSEMBLE_JSON, found {item!r}")
        clips = json.loads(Path(path).read_text())["clips"]
        paths[label] = path
        rows[label] = {clip: course(c["models"][MODEL], c["members"]) for clip, c in clips.items()}
    clips = list(next(iter(rows.values())))
    lines = [
        "# The hem's course through each held-out turn",
        "",
        "Made by `python bench/quality/flare_course.py` (its docstring gives the command) "
        f"on {time.strftime('%Y-%m-%d', time.gmtime())} from the flare series of "
        + ", ".join(f"{label} (`{path}`)" for label, path in paths.items())
        + ". Over the 61 frames around each clip's fastest turn: the hem's flare over the "
        "members' mean; the share of frames inside the members' range (the target: 80 %); "
        "how far outside it on average and at most (cm); the RMS distance from the members' "
        "mean flare (cm).",
        "",
    ]
    for clip in clips:
        lines += [
            f"## `{clip}`",
            "",
            "| candidate | flare / members' mean | in band % | outside by, mean cm | at most cm "
            "| RMS to the members' mean cm |",
            "|---|---:|---:|---:|---:|---:|",
        ]
        for label, r in rows.items():
            c = r[clip]
            lines.append(
                f"| {label} | {c['ratio']:.2f} | {100 * c['in_band']:.0f} | {c['gap_cm']:.2f} "
                f"| {c['max_gap_cm']:.1f} | {c['rms_cm']:.2f} |"
            )
        lines.append("")
    Path(args.out).write_text("\n".join(lines))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
