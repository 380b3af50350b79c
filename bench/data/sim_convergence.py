"""How far the cloth solver is from converged: the garment's drape on the rest pose under
several solver schedules, against the same drape solved with many more iterations.

Usage:
    .venv/bin/python bench/data/sim_convergence.py [--preset dance] [--workers 2]
        [--run NAME:KEY=VALUE,KEY=VALUE ...] [--out docs/results/SIM_SPEED.md]

Each ``--run`` settles the preset's garment on the rest pose (the settle phase every clip
starts with: ``settle_seconds`` of gravity with ``settle_damping``) with the preset's cloth
configuration and the given changes (``substeps``, ``iterations``, ``chebyshev_rho``,
``initial_guess``), one thread each. Without ``--run`` the default set: the preset as it is
(20 substeps x 5 iterations), 10 substeps, Chebyshev's acceleration, the adaptive initial
guess, and references with 8 times the iterations. For each: seconds, edge strain (median and
99th percentile), the hem's height and radius from the waist's axis, and the mean distance
of every vertex from the first reference's drape.

What it shows: a drape that depends on the schedule by more than clip-to-clip chaos is a
drape whose iterations have not converged; comparing a faster schedule with the preset's
(bench/data/sim_quality.py) then holds it to the preset's own error.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import time
from concurrent.futures import ProcessPoolExecutor
from datetime import date

import numpy as np

from loosefit.eval.report import write_section
from loosefit.eval.sim_runs import parse_candidate

SECTION = "## How far from converged"  # of docs/results/SIM_SPEED.md

DEFAULT_RUNS = (
    "preset:",
    "s10:substeps=10",
    "cheb0.9:chebyshev_rho=0.9",
    "s10i7-cheb0.95:substeps=10,iterations=7,chebyshev_rho=0.95",
    'adaptive:initial_guess="adaptive"',
    "i40 (reference):iterations=40",
    'i40-adaptive:iterations=40,initial_guess="adaptive"',
    "s80i10:substeps=80,max_substeps=80,iterations=10",
)


def drape(preset_name: str, changes: dict) -> dict:
    """One drape, in a process of its own (one torch thread)."""
    import torch

    from loosefit.garment.mesh_checks import hem_loop
    from loosefit.garment.quality import edge_strain
    from loosefit.sim.driver import settle
    from loosefit.sim.presets import preset
    from loosefit.sim.workers import Worker

    torch.set_num_threads(1)
    config = preset(preset_name)
    cloth = dataclasses.replace(config.cloth, **changes)
    worker = Worker.build(dataclasses.replace(config, cloth=cloth))
    template = worker.template
    t0 = time.perf_counter()
    g = settle(worker.avatar, template, cloth, 30.0)
    seconds = time.perf_counter() - t0
    strain, _ = edge_strain(g[None], template)
    hem = g[hem_loop(template.vertices, template.faces)]
    waist = g[template.waist].mean(0)
    return {
        "vertices": g,
        "seconds": seconds,
        "strain_p50": float(np.median(strain)),
        "strain_p99": float(np.percentile(strain, 99)),
        "hem_height": float(hem[:, 2].mean() - waist[2]),
        "hem_radius": float(np.linalg.norm((hem - waist)[:, :2], axis=1).mean()),
    }


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--preset", default="dance")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--run", action="append", default=[], help="NAME:KEY=VALUE,...")
    p.add_argument(
        "--out",
        default="",
        help=f"a Markdown page (docs/results/SIM_SPEED.md) whose section '{SECTION}' the tables "
        "replace, the rest of the page kept",
    )
    args = p.parse_args(argv)
    runs = [parse_candidate(s) for s in (args.run or DEFAULT_RUNS)]
    os.environ["OMP_NUM_THREADS"] = "1"
    with ProcessPoolExecutor(args.workers) as pool:
        futures = [pool.submit(drape, args.preset, changes) for _, changes in runs]
        results = [f.result() for f in futures]
    ref_index = next((i for i, (n, _) in enumerate(runs) if "reference" in n), None)
    ref = results[ref_index]["vertices"] if ref_index is not None else None
    machine = f"{platform.node()}, {os.cpu_count()} cores, one thread a run"
    command = " ".join(argv if argv is not None else os.sys.argv[1:])
    lines = [
        "# The drape on the rest pose under several solver schedules",
        "",
        f"`python bench/data/sim_convergence.py {command}`;"
        f" {machine}, {args.workers} at once; {date.today()}.",
        "",
        "| run | changes | s | strain p50 | strain p99 | hem below the waist (m) "
        "| hem radius (m) | mean distance to the reference (cm) |",
        "|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    for (name, changes), r in zip(runs, results, strict=True):
        label = ", ".join(f"{k}={v}" for k, v in changes.items()) or "(preset)"
        dist = ""
        if ref is not None:
            dist = f"{100 * np.linalg.norm(r['vertices'] - ref, axis=1).mean():.2f}"
        lines.append(
            f"| {name} | {label} | {r['seconds']:.0f} | {r['strain_p50']:.4f} | "
            f"{r['strain_p99']:.4f} | {-r['hem_height']:.4f} | {r['hem_radius']:.4f} | {dist} |"
        )
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        write_section(args.out, SECTION, text)


if __name__ == "__main__":
    main()
