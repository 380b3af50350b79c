"""How much faster any schedule of the cloth solver could simulate the `dance` corpus: the
substeps its motions demand, and what a substep costs.

Usage:
    .venv/bin/python bench/data/sim_bound.py [--data datasets/dance] [--preset dance]
        [--profile-clip 05_10] [--profile-frames 12] [--out docs/results/SIM_SPEED.md]

The data set is the simulated `dance` corpus, unpacked (``python3
../shared/datasets/lfz.py unpack ../shared/datasets/dance.lfz. datasets/dance``). Its
sequences carry the motions as they were simulated (pose-corrected) and the cloth the
preset made of them.

1. **What a substep costs.** One clip's first ``--profile-frames`` frames, simulated with the
   preset (graph capture off, one thread) and timed phase by phase as
   ``bench/speed/sim_profile.py`` does: ``I``, the seconds of one VBD iteration (the solver's
   iterations, exclusive); ``F``, the seconds of everything else a substep does (contact
   detection with the body and with itself, the forward step, truncation, the body's
   posing and refit), and the rest of a frame. A schedule of ``s`` substeps of ``i``
   iterations costs about ``s (F + i I)`` a frame; the preset's ``20 x 5`` is the
   reference.
2. **The substeps the motions demand.** With self-contact on, Newton moves a cloth vertex
   at most ``0.85 (self_contact_margin + self_contact_gap)`` in a substep (12.75 mm for
   the preset). Whatever moves faster than that at the garment drags the cloth through
   itself or leaves it behind in the body: the waistband (glued to the body) and the body
   where the cloth can meet it (legs, hips, a hand at the skirt;
   ``timeline.body_moves``). For every clip of the corpus, each frame's least substeps
   (``timeline.substep_schedule`` from one substep up) under three limits:

   * ``cap``: the waistband and the body each at most the cap a substep;
   * ``body 1 cm``: the body at most 1 cm (the one limit measured to keep the ballet clip
     05_10 in the quality gate, docs/results/SIM_SPEED.md), the waistband at the cap;
   * ``cloth``: the recorded cloth's own fastest vertex at most the cap a substep (the
     preset's cloth; a bound for a solver that makes the same cloth).

3. **The bound.** Over the corpus (its frames, settle and blend left out: counting them
   only raises the bound), the speed-up of the cheapest schedule that meets each limit
   with ``i`` iterations a substep, against the preset's own schedule, for ``i`` = 1 to 5.
   Any schedule of this solver with fewer iterations than the preset makes different
   cloth (docs/results/SIM_SPEED.md); the bound says how much faster it could be at best.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from datetime import date
from pathlib import Path

import numpy as np
import torch

SECTION = "## The bound on any schedule"  # of docs/results/SIM_SPEED.md

LIMITS = ("cap", "body 1 cm", "cloth")


def truncation_cap(cloth) -> float:
    """m: the farthest Newton's VBD moves a cloth vertex in one substep with self-contact."""
    return 0.85 * (cloth.self_contact_margin + cloth.self_contact_gap)


def demands(avatar, template, motion, garment: np.ndarray, cloth) -> dict[str, np.ndarray]:
    """(T - 1,) least substeps of each motion frame under each of :data:`LIMITS`."""
    import loosefit.sim.driver as driver
    from loosefit.sim.timeline import body_moves, collider_meshes, substep_schedule, timeline
    from loosefit.sim.waist import glued_points

    line = timeline(avatar, motion, cloth)
    body_faces, limb_faces, _ = collider_meshes(avatar, cloth)
    sim = driver._batch_simulator(
        template, [line], body_faces, limb_faces, cloth, motion.fps, seeds=[0]
    )
    collider = line.collider[line.n_pre :]  # the motion's frames: settle and blend left out
    waist = np.stack([glued_points(sim.glue, b, body_faces) for b in collider])
    cap = truncation_cap(cloth)
    moves = body_moves(collider, waist)

    def least(body_limit: float) -> np.ndarray:
        return substep_schedule(waist, 1, 10_000, cap, body_moves=moves, max_body_move=body_limit)

    step = np.linalg.norm(np.diff(garment.astype(np.float64), axis=0), axis=-1).max(-1)
    return {
        "cap": least(cap),
        "body 1 cm": least(0.01),
        "cloth": np.maximum(1, np.ceil(step / cap)).astype(np.int64),
    }


def substep_costs(worker, motion, cloth, frames: int) -> dict:
    """F (s a substep, outside the iterations) and I (s an iteration) from a profiled run."""
    from loosefit.eval.sim_runs import ONCE, profiled_run

    res, timer, _, wall = profiled_run(
        worker.avatar, worker.template, motion.slice(0, frames), cloth
    )
    once = sum(timer.self_[k] for k in ONCE.values())
    steps = res.preroll_frames + frames - 1
    substeps = res.stats["substeps_mean"] * steps
    iterations = timer.calls["solver: VBD iterations"]
    it_seconds = timer.self_["solver: VBD iterations"]
    loop = wall - once
    return {
        "F": (loop - it_seconds) / substeps,
        "I": it_seconds / iterations,
        "frames": steps,
        "substeps": substeps / steps,
        "iterations": iterations / substeps,
        "seconds_per_frame": loop / steps,
    }


def bound_table(clips: list[dict], costs: dict, preset_iterations: int) -> dict:
    """Corpus speed-ups of the cheapest schedule meeting each limit at 1..preset iterations."""
    F, I = costs["F"], costs["I"]
    frames = sum(c["frames"] for c in clips)
    preset = sum(c["preset_substeps"] * c["frames"] for c in clips) * (F + preset_iterations * I)
    out = {}
    for limit in LIMITS:
        substeps = sum(c[limit] * c["frames"] for c in clips)
        out[limit] = {
            "substeps_mean": substeps / frames,
            "speedup": {
                i: preset / (substeps * (F + i * I)) for i in range(1, preset_iterations + 1)
            },
        }
    return out


def markdown(clips, costs, table, cloth, args, machine) -> str:
    cap_mm = 1000 * truncation_cap(cloth)
    frames = sum(c["frames"] for c in clips)
    lines = [
        "# How much faster any schedule could be: the substeps the corpus demands",
        "",
        f"`python bench/data/sim_bound.py {' '.join(args)}`; {machine}; {date.today()}.",
        "",
        f"## What a substep costs (clip {costs['clip']}, {costs['frames']} frames stepped, "
        f"{costs['substeps']:.1f} substeps x {costs['iterations']:.0f} iterations)",
        "",
        "| | ms |",
        "|---|---:|",
        f"| `F`: a substep outside the iterations | {1000 * costs['F']:.1f} |",
        f"| `I`: one VBD iteration | {1000 * costs['I']:.1f} |",
        f"| a frame of the preset, `{costs['substeps']:.0f} (F + {costs['iterations']:.0f} I)` "
        f"| {1000 * costs['substeps'] * (costs['F'] + costs['iterations'] * costs['I']):.0f} |",
        f"| a frame as measured | {1000 * costs['seconds_per_frame']:.0f} |",
        "",
        f"## Substeps a motion frame demands ({len(clips)} clips, {frames} motion frames; "
        f"the cap: {cap_mm:.2f} mm a substep)",
        "",
        "| clip | frames | kept | preset (mean) | cap: mean | max | body 1 cm: mean | max "
        "| cloth: mean | max |",
        "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for c in clips:
        lines.append(
            f"| {c['clip']} | {c['frames']} | {'yes' if c['kept'] else 'no'} "
            f"| {c['preset_substeps']:.1f} "
            + " ".join(f"| {c[k]:.1f} | {c[k + ' max']}" for k in LIMITS)
            + " |"
        )
    n = len(next(iter(table.values()))["speedup"])
    lines += [
        "",
        "## The bound: the corpus's speed-up at best, against the preset",
        "",
        "Each limit's least substeps, frame by frame, at `i` iterations each, against the "
        "preset's schedule at its iterations; the clips the gate keeps and flags alike.",
        "",
        "| limit | substeps a frame | " + " | ".join(f"i = {i}" for i in range(1, n + 1)) + " |",
        "|---|---:|" + "---:|" * n,
    ]
    for limit, row in table.items():
        lines.append(
            f"| {limit} | {row['substeps_mean']:.1f} | "
            + " | ".join(f"{v:.2f}x" for v in row["speedup"].values())
            + " |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--data", default="datasets/dance", help="the unpacked dance corpus")
    p.add_argument("--preset", default="dance")
    p.add_argument("--profile-clip", default="05_10")
    p.add_argument("--profile-frames", type=int, default=12)
    p.add_argument("--clips", default="", help="comma-separated: only these (default: all)")
    p.add_argument(
        "--out",
        default="",
        help=f"a Markdown page (docs/results/SIM_SPEED.md) whose section '{SECTION}' the tables "
        "replace, the rest of the page kept",
    )
    p.add_argument("--json", default="", help="a JSON file for the figures")
    args = p.parse_args(argv)

    from loosefit.data.format import DatasetReader
    from loosefit.sim.presets import preset
    from loosefit.sim.workers import Worker

    if not (Path(args.data) / "manifest.json").is_file():
        raise SystemExit(
            f"{args.data}: no data set; unpack the corpus first: python3 "
            "../shared/datasets/lfz.py unpack ../shared/datasets/dance.lfz. datasets/dance"
        )
    reader = DatasetReader(args.data)
    torch.set_num_threads(1)
    config = preset(args.preset)
    cloth = config.cloth
    worker = Worker.build(config)
    sequences = reader.manifest["sequences"]
    names = args.clips.split(",") if args.clips else sorted(sequences)
    for name in names:
        if name not in sequences:
            raise SystemExit(f"{args.data}: no sequence {name!r} (it has {', '.join(sequences)})")

    clips = []
    t0 = time.perf_counter()
    for n, name in enumerate(names):
        seq = reader.read(name)
        need = demands(worker.avatar, worker.template, seq.motion, seq.garment_vertices, cloth)
        entry = {
            "clip": name,
            "frames": seq.motion.num_frames - 1,
            "kept": sequences[name]["status"] != "flagged",
            "preset_substeps": float(sequences[name]["substeps_mean"]),
        }
        for k, v in need.items():
            entry[k], entry[k + " max"] = float(v.mean()), int(v.max())
        clips.append(entry)
        rate = (n + 1) / (time.perf_counter() - t0)
        print(
            f"[{n + 1}/{len(names)}] {name}: "
            + ", ".join(f"{k} {entry[k]:.1f}" for k in LIMITS)
            + f" ({rate * 60:.1f} clips/min, ETA {(len(names) - n - 1) / rate:.0f} s)",
            flush=True,
        )

    motion = reader.read(args.profile_clip).motion
    costs = substep_costs(worker, motion, cloth, args.profile_frames)
    costs["clip"] = args.profile_clip
    table = bound_table(clips, costs, cloth.iterations)
    machine = (
        f"{platform.node()}, {platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} cores, one thread"
    )
    command = argv if argv is not None else os.sys.argv[1:]
    text = markdown(clips, costs, table, cloth, command, machine)
    print(text)
    if args.out:
        from loosefit.eval.report import write_section

        write_section(args.out, SECTION, text + "\n")
    if args.json:
        Path(args.json).write_text(
            json.dumps({"costs": costs, "clips": clips, "bound": table}, indent=1) + "\n"
        )


if __name__ == "__main__":
    main()
