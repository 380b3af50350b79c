"""Cloth simulation on a GPU: frames per second by batch size, with and without graph capture,
and what a start costs.

Usage (on a lent GPU, after ``scripts/gpu_pipeline.py receive``; one call)::

    python3 bench/speed/sim_gpu.py --device cuda:0 --batches 1,8,32,64 --frames 40 \\
        --budget 420 --out $OUT

At toy size on any machine (what ``tests/test_gpu_pipeline.py`` runs, through
``scripts/gpu_pipeline.py sim-speed``)::

    python bench/speed/sim_gpu.py --tiny --device cpu --batches 1,2 --frames 3 --out /tmp/sim-gpu

The start is timed phase by phase from the process's first line: the imports, the body and
garment (anny's model cache), the clips' bodies (``--clips`` distinct clips of the preset,
pose-corrected as a data set's worker corrects them and posed over their timelines, in
parallel processes), and the first simulated frames (warp loading or compiling its
modules). Then each batch size ``K`` runs ``K`` clips at once (the distinct clips in turn,
each with its own seed), their first ``--frames`` motion frames after the settle and blend,
once for each ``--capture``: ``on``, a whole frame replayed as one recorded graph;
``substeps``, one graph a substep with the bodies posed between them; ``off``, launch by
launch. The bodies are prepared once and reused by every run: what this table measures is
the simulation. Frames per second count every simulated clip frame (settle and blend
included) over the loop's seconds; the model's build is given apart. Every run's clips go
through the data set's quality gate; a flagged clip is counted in the table. ``--phases``
times a frame's phases, the device synchronised after each. A run that would pass
``--budget`` seconds (from the start) is left out and said so.

Writes ``sim_gpu.md`` and ``sim_gpu.json`` into ``--out``.
"""

from __future__ import annotations

import time

T_START = time.perf_counter()  # noqa: E402 (the start is timed from here)

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import os  # noqa: E402
import platform  # noqa: E402
from datetime import date  # noqa: E402
from pathlib import Path  # noqa: E402


def _since() -> float:
    return time.perf_counter() - T_START


def _machine(device: str) -> str:
    text = f"{platform.node()}, {os.cpu_count()} CPU cores"
    if device.startswith("cuda"):
        import torch

        text += f", {torch.cuda.get_device_name(0)}"
    return text


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--preset", default="dance")
    p.add_argument("--bvh", default=None, help="the salsa folder (dance: cmu-ballet beside it)")
    p.add_argument("--device", default="cuda:0")
    p.add_argument("--batches", default="1,8,32,64")
    p.add_argument("--frames", type=int, default=40, help="motion frames of each clip")
    p.add_argument("--clips", type=int, default=8, help="distinct clips (each seed a copy)")
    p.add_argument(
        "--capture",
        default="on,substeps,off",
        help="on (a frame a graph), substeps (a substep a graph), off; comma-separated",
    )
    p.add_argument("--phases", action="store_true", help="time a frame's phases (synchronised)")
    p.add_argument("--set", action="append", default=[], help="cloth KEY=VALUE")
    p.add_argument("--budget", type=float, default=420.0, help="seconds from the start")
    p.add_argument("--tiny", action="store_true", help="the tiny preset (a test's size)")
    p.add_argument("--out", default=os.environ.get("OUT", "out/sim-gpu"))
    args = p.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    start: dict[str, float] = {}
    mark = _since()

    def phase(name: str) -> None:
        nonlocal mark
        now = _since()
        start[name] = now - mark
        mark = now
        print(f"[{now:6.1f} s] {name}: {start[name]:.1f} s", flush=True)

    import numpy as np
    import torch
    import warp as wp

    import loosefit.sim.driver as driver
    import loosefit.sim.stepper as stepper
    from loosefit.eval.sim_runs import Timer
    from loosefit.sim.driver import simulate_batch
    from loosefit.sim.jobs import plan_jobs
    from loosefit.sim.manifest import clip_entry
    from loosefit.sim.presets import preset
    from loosefit.sim.workers import Worker

    torch.set_num_threads(1)
    wp.init()
    phase("imports (torch, warp, loosefit)")
    config = preset("tiny" if args.tiny else args.preset, args.bvh)
    changes = {}
    for item in args.set:
        key, _, value = item.partition("=")
        changes[key] = json.loads(value)
    cloth = dataclasses.replace(config.cloth, device=args.device, **changes)
    config = dataclasses.replace(config, cloth=cloth)
    worker = Worker.build(config)
    phase("body and garment (anny's model cache)")
    jobs = [j for j in plan_jobs(config) if not j.name.startswith("chain")][: args.clips]
    batches = [int(b) for b in args.batches.split(",")]
    motions, lines = _prepare(config, jobs, args.frames)
    cached = dict(zip((id(m) for m in motions), lines, strict=True))
    real_timeline = driver.timeline
    driver.timeline = lambda avatar, motion, *a, **k: (
        cached.get(id(motion)) or real_timeline(avatar, motion, *a, **k)
    )
    phase(f"{len(motions)} clips' bodies over their timelines")
    first = dataclasses.replace(cloth, settle_seconds=0.0, blend_seconds=0.0)
    simulate_batch(worker.avatar, worker.template, [motions[0].slice(0, 2)], first)
    phase("first frames (warp's modules loaded or compiled)")
    first_frames = _since()

    rows = []
    for K in batches:
        previous = None  # the first clip's cloth in the last run of this batch size
        for capture in args.capture.split(","):
            if _since() > args.budget:
                rows.append({"batch": K, "capture": capture, "skipped": "budget spent"})
                print(f"batch {K}, capture {capture}: left out (budget)", flush=True)
                continue
            chosen = [motions[i % len(motions)] for i in range(K)]
            picked = [jobs[i % len(motions)] for i in range(K)]
            seeds = [j.seed + i // len(motions) for i, j in enumerate(picked)]
            run_cloth = dataclasses.replace(cloth, capture=capture != "off")
            stepper.ClothSimulator.record_frames = capture == "on"
            replays = {True: 0, False: 0}  # frames replayed as one graph, and refused
            replay = stepper.ClothSimulator._replay_frame

            def counted(sim, n, _replay=replay, _seen=replays):
                done = _replay(sim, n)
                _seen[done] += 1
                return done

            timer = Timer()
            timer.replace(stepper.ClothSimulator, "_replay_frame", counted)
            _phases(timer, args.phases and args.device.startswith("cuda"))
            t0 = time.perf_counter()
            try:
                results = simulate_batch(
                    worker.avatar, worker.template, chosen, run_cloth, seeds=seeds
                )
            finally:
                timer.restore()
            wall = time.perf_counter() - t0
            stats = results[0].stats
            loop = stats["simulate_seconds"] * K
            build = stats["build_seconds"] * K
            frames = sum(r.stats["frames_simulated"] for r in results)
            flagged = [
                j.name
                for j, m, r in zip(picked, chosen, results, strict=True)
                if clip_entry(config, j, m, r)["status"] != "done"
            ]
            row = {
                "batch": K,
                "capture": capture,
                "clip_frames": frames,
                "batch_frames": stats["batch_frames"],
                "loop_seconds": loop,
                "build_seconds": build,
                "wall_seconds": wall,
                "frames_per_second": frames / loop,
                "substeps_mean": float(np.mean([r.stats["substeps_mean"] for r in results])),
                "flagged": flagged,
                "phases": {k: v / stats["batch_frames"] for k, v in timer.self_.items()},
                "frames_as_one_graph": replays[True],
                "frame_graph_refused": replays[False] > 0,
            }
            g = results[0].garment_vertices
            if previous is not None:  # the same clip, replayed or launched: the same cloth
                row["gap_to_other_mm"] = float(1000 * np.abs(g - previous).max())
            previous = g
            rows.append(row)
            print(
                f"batch {K:3d}, capture {capture:3s}: {row['frames_per_second']:8.1f} frames/s "
                f"({frames} clip frames in {loop:.1f} s; build {build:.1f} s; "
                f"{len(flagged)} flagged; {replays[True]} frames as one graph"
                + (", a frame's recording refused)" if replays[False] else ")"),
                flush=True,
            )
            _write(out, args, start, first_frames, rows, _machine(args.device), argv)
    _write(out, args, start, first_frames, rows, _machine(args.device), argv)
    return 0


def _phases(timer, on: bool) -> None:
    """With ``on``, ``timer`` (a :class:`sim_profile.Timer`) times a frame's phases, the
    device synchronised after each (slower, but the seconds are each phase's own)."""
    from newton.solvers import SolverVBD

    import loosefit.sim.driver as driver
    import loosefit.sim.stepper as stepper

    if not on:
        return
    for owner, attr, label in (
        (stepper.ClothSimulator, "step_frame", "frame: body upload, the rest"),
        (SolverVBD, "rebuild_bvh", "self-contact BVH rebuild"),
        (stepper.ClothSimulator, "_replay_frame", "a frame's graph (recorded or replayed)"),
        (stepper.ClothSimulator, "_pose_body", "body posed and refitted"),
        (stepper.ClothSimulator, "_substep", "a substep launched"),
        (driver, "_record_frame", "frame recorded and checked"),
    ):
        timer.replace(owner, attr, _synced(getattr(owner, attr)))
        timer.wrap(owner, attr, label)


def _synced(inner):
    """``inner``, then the device synchronised (not inside a recording: nothing runs there)."""
    import warp as wp

    def synced(*args, **kwargs):
        out = inner(*args, **kwargs)
        if not wp.get_device().is_capturing:
            wp.synchronize()
        return out

    return synced


def _prepare_one(config, job, frames: int):
    """One clip's motion (its first ``frames`` frames, pose-corrected as the data set's
    worker corrects it) and its timeline, in a process of its own."""
    import torch

    from loosefit.sim.timeline import timeline
    from loosefit.sim.workers import Worker

    torch.set_num_threads(1)
    worker = Worker.build(config)
    from loosefit.sim.jobs import job_motion

    motions = dataclasses.replace(config.motions, max_frames=frames)  # corrected as a data set's
    motion = job_motion(dataclasses.replace(config, motions=motions), job, worker.avatar)
    return motion, timeline(worker.avatar, motion, config.cloth)


def _prepare(config, jobs, frames: int):
    """Every clip's motion and timeline, prepared in parallel on the CPU."""
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    cpu = dataclasses.replace(config, cloth=dataclasses.replace(config.cloth, device="cpu"))
    workers = max(1, min(len(jobs), (os.cpu_count() or 2) - 1))
    # spawned, not forked: this process has CUDA open
    with ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn")) as pool:
        done = list(pool.map(_prepare_one, [cpu] * len(jobs), jobs, [frames] * len(jobs)))
    return [m for m, _ in done], [t for _, t in done]


def _write(out: Path, args, start, first_frames, rows, machine, argv) -> None:
    record = {
        "machine": machine,
        "date": str(date.today()),
        "device": args.device,
        "preset": "tiny" if args.tiny else args.preset,
        "frames": args.frames,
        "start": start,
        "first_frames_after": first_frames,
        "runs": rows,
    }
    (out / "sim_gpu.json").write_text(json.dumps(record, indent=1) + "\n")
    lines = [
        "# Cloth simulation on a GPU: frames per second by batch",
        "",
        f"`python bench/speed/sim_gpu.py "
        f"{' '.join(argv if argv is not None else os.sys.argv[1:])}`;"
        f" {machine}; {date.today()}.",
        "",
        "The start, from the process's first line:",
        "",
        "| phase | s |",
        "|---|---:|",
        *(f"| {k} | {v:.1f} |" for k, v in start.items()),
        f"| **first simulated frames after** | **{first_frames:.1f}** |",
        "",
        f"Each clip: its first {args.frames} motion frames after the settle and blend.",
        "",
        "| clips at once | graph capture | frames/s | clip frames | loop (s) | build (s) "
        "| substeps | flagged | first clip vs the other capture (mm) |",
        "|---:|---|---:|---:|---:|---:|---:|---|---:|",
    ]
    for r in rows:
        if "skipped" in r:
            lines.append(f"| {r['batch']} | {r['capture']} | {r['skipped']} | | | | | | |")
            continue
        lines.append(
            f"| {r['batch']} | {r['capture']} | {r['frames_per_second']:.1f} | "
            f"{r['clip_frames']} | {r['loop_seconds']:.1f} | {r['build_seconds']:.1f} | "
            f"{r['substeps_mean']:.1f} | {', '.join(r['flagged']) or 'none'} | "
            + (f"{r['gap_to_other_mm']:.3f} |" if "gap_to_other_mm" in r else " |")
        )
    timed = [r for r in rows if r.get("phases")]
    if timed:
        lines += ["", "A frame's phases (s a batch frame, the device synchronised after each):", ""]
        for r in timed:
            parts = ", ".join(f"{k} {v:.4f}" for k, v in sorted(r["phases"].items()))
            lines.append(f"- {r['batch']} clips, capture {r['capture']}: {parts}")
    (out / "sim_gpu.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    raise SystemExit(main())
