"""A faster cloth configuration against the unchanged one: speed, and what it does to the cloth.

Usage:
    .venv/bin/python bench/data/sim_quality.py [--preset dance] [--clips 60_01,05_10]
        [--frames 120] [--workers 2] [--candidate NAME:KEY=VALUE,KEY=VALUE ...]
        [--cache out/sim_quality] [--out docs/results/SIM_SPEED.md]

Each clip of the preset (its first ``--frames`` motion frames, prepared as the data set's
worker prepares it) is simulated three ways and more, one thread each:

* ``base``: the preset's cloth configuration, the clip's own seed;
* ``seed+1``, ``seed+2`` (``--seeds``): the same with the next seeds (the start's 0.1 mm
  jitter). Cloth is chaotic: how far other seeds of the unchanged solver drift from
  ``base`` is the tolerance a change is held to;
* each ``--candidate``: the preset's configuration with the given changes, the clip's seed.

For each run: seconds per frame (settle and blend included), the data set's quality gate
(the preset's limits: flagged or kept, and why), the edge strain (median and 99th percentile
over every frame), the hem (mean height above the floor and mean radius from the waist's
axis, over the motion frames) and, against ``base``, the distance of every vertex (RMS over
the motion frames, and the worst frame's mean). A candidate holds when the gate keeps what
it keeps for ``base`` and each figure differs from ``base``'s by no more than another seed's
does (or by less than a floor: 1 mm for the hem, 0.002 for strain), on every clip. The
speed-up is the ratio of a clip's whole simulation (settle and blend included), so that a
change that simulates fewer frames counts.

Runs are kept in ``--cache`` (one ``.npz`` each, named by clip, frames and configuration), so
a rerun with another candidate simulates only that one.
"""

from __future__ import annotations

import argparse
import os
import platform
from concurrent.futures import ProcessPoolExecutor
from datetime import date

import numpy as np

from loosefit.eval.report import write_section
from loosefit.eval.sim_runs import candidate_config, parse_candidate, simulate_run

SECTIONS = {  # the sections of docs/results/SIM_SPEED.md a run writes
    "quality": "## Speed against quality",
    "accelerated": "## Accelerated schedules",
}
HEM_FLOOR = 0.001  # m: a hem figure closer than this to base's holds whatever the seeds do
STRAIN_FLOOR = 0.002
FLOORS = {
    "hem_height": HEM_FLOOR,
    "hem_radius": HEM_FLOOR,
    "strain_p50": STRAIN_FLOOR,
    "strain_p99": STRAIN_FLOOR,
}


def figures(run: dict, template, base: dict | None) -> dict:
    """Strain, hem and (against ``base``) vertex distance of one run's motion frames."""
    from loosefit.garment.mesh_checks import hem_loop
    from loosefit.garment.quality import edge_strain

    g = run["garment"]  # (T, V, 3)
    strain, _ = edge_strain(g, template)
    hem = hem_loop(template.vertices, template.faces)
    waist = g[:, template.waist].mean(1)  # (T, 3)
    hem_xyz = g[:, hem]
    radius = np.linalg.norm((hem_xyz - waist[:, None])[..., :2], axis=-1).mean()
    out = {
        "strain_p50": float(np.median(strain)),
        "strain_p99": float(np.percentile(strain, 99)),
        "hem_height": float(hem_xyz[..., 2].mean()),  # the floor is at z = 0
        "hem_radius": float(radius),
    }
    if base is not None:
        d = np.linalg.norm(g - base["garment"], axis=-1)  # (T, V)
        out["rms_to_base_cm"] = float(100 * np.sqrt((d**2).mean()))
        out["worst_frame_to_base_cm"] = float(100 * d.mean(1).max())
    return out


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--preset", default="dance")
    p.add_argument("--clips", default="60_01,05_10")
    p.add_argument("--frames", type=int, default=120)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--seeds", type=int, default=2, help="other seeds of base: the tolerance")
    p.add_argument("--candidate", action="append", default=[], help="NAME:KEY=VALUE,...")
    p.add_argument("--cache", default="out/sim_quality")
    p.add_argument(
        "--out",
        default="",
        help="a Markdown page (docs/results/SIM_SPEED.md) whose section --section the tables "
        "replace, the rest of the page kept",
    )
    p.add_argument(
        "--section",
        choices=sorted(SECTIONS),
        default="quality",
        help="which section of --out: " + "; ".join(f"{k}: '{v}'" for k, v in SECTIONS.items()),
    )
    args = p.parse_args(argv)

    candidates = dict(parse_candidate(spec) for spec in args.candidate)
    clips = args.clips.split(",")
    seeds = [(f"seed+{k}", k, {}) for k in range(1, args.seeds + 1)]
    runs = [("base", 0, {}), *seeds] + [(n, 0, c) for n, c in candidates.items()]
    jobs = [(clip, name, shift, changes) for clip in clips for name, shift, changes in runs]
    os.environ["OMP_NUM_THREADS"] = "1"  # the runs' processes: one thread each
    with ProcessPoolExecutor(args.workers) as pool:
        futures = {
            (clip, name): pool.submit(
                simulate_run, args.preset, clip, args.frames, shift, changes, args.cache
            )
            for clip, name, shift, changes in jobs
        }
        results = {k: f.result() for k, f in futures.items()}

    from loosefit.sim.workers import Worker

    template = Worker.build(candidate_config(args.preset, {})).template
    table = {}
    for clip in clips:
        base = results[(clip, "base")]
        for name, _, _ in runs:
            run = results[(clip, name)]
            if run["garment"] is None:
                table[(clip, name)] = {"status": "diverged", "reason": run["reason"]}
                continue
            table[(clip, name)] = {
                **{k: run[k] for k in ("status", "reason", "seconds_per_frame", "substeps_mean")},
                "simulate_seconds": run["seconds_per_frame"] * run["frames_stepped"],
                **figures(run, template, None if name == "base" else base),
            }
    verdicts = {}
    for name in candidates:
        ok, why = True, []
        for clip in clips:
            b, c = table[(clip, "base")], table[(clip, name)]
            others = [table[(clip, n)] for n, _, _ in seeds if "strain_p50" in table[(clip, n)]]
            if c["status"] != "done" and b["status"] == "done":
                ok = False
                why.append(f"{clip}: flagged ({c.get('reason', '')})")
                continue
            if "strain_p50" not in c:
                continue
            for key, floor in FLOORS.items():
                tol = max([abs(o[key] - b[key]) for o in others] + [floor])
                if abs(c[key] - b[key]) > tol:
                    ok = False
                    why.append(f"{clip}: {key} {c[key]:.4f} vs {b[key]:.4f} (tolerance {tol:.4f})")
            spread = max([o["rms_to_base_cm"] for o in others] + [0.1])
            if c["rms_to_base_cm"] > spread:
                ok = False
                why.append(
                    f"{clip}: {c['rms_to_base_cm']:.2f} cm from base, seeds up to {spread:.2f}"
                )
        verdicts[name] = (ok, why)

    machine = f"{platform.node()}, {os.cpu_count()} cores, one thread a run"
    lines = [
        "# A faster cloth configuration against the unchanged one",
        "",
        f"`python bench/data/sim_quality.py "
        f"{' '.join(argv if argv is not None else os.sys.argv[1:])}`;"
        f" {machine}, {args.workers} runs at once; {date.today()}.",
        "",
        "| clip | run | changes | s a frame | speed-up (clip) | substeps | gate | strain p50 "
        "| strain p99 | hem height (m) | hem radius (m) | RMS to base (cm) | worst frame (cm) |",
        "|---|---|---|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|",
    ]
    for clip in clips:
        base_wall = table[(clip, "base")]["simulate_seconds"]
        for name, _, changes in runs:
            r = table[(clip, name)]
            if "strain_p50" not in r:
                lines.append(f"| {clip} | {name} | {changes} | | | | {r['status']} | | | | | | |")
                continue
            rms = f"{r['rms_to_base_cm']:.2f}" if "rms_to_base_cm" in r else ""
            worst = f"{r['worst_frame_to_base_cm']:.2f}" if "worst_frame_to_base_cm" in r else ""
            label = ", ".join(f"{k}={v}" for k, v in changes.items()) or "(preset)"
            lines.append(
                f"| {clip} | {name} | {label} | {r['seconds_per_frame']:.3f} | "
                f"{base_wall / r['simulate_seconds']:.2f}x | {r['substeps_mean']:.1f} | "
                f"{r['status']} | {r['strain_p50']:.4f} | {r['strain_p99']:.4f} | "
                f"{r['hem_height']:.4f} | {r['hem_radius']:.4f} | {rms} | {worst} |"
            )
    lines.append("")
    for name, (ok, why) in verdicts.items():
        lines.append(f"- **{name}**: " + ("holds" if ok else "does not hold: " + "; ".join(why)))
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        write_section(args.out, SECTIONS[args.section], text)


if __name__ == "__main__":
    main()
