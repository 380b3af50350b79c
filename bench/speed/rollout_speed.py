"""Learned rollout against the simulation that made its data: seconds per frame, same garment.

Times, in one run, on the same garment and the same motion:

* the rollout of a trained model (``loosefit animate``'s work: motion features,
  the encoder, the frozen decoders, one frame after another), then with the detail
  stage (paper 3.4, when the checkpoint has one packaged beside it) and with
  collision handling (3.5): the whole pipeline, each stage's milliseconds per frame
  apart, with 1 CPU thread and with all of them, and on the GPU when there is one;
* Newton's VBD simulation of that garment on the first motion, with the cloth
  configuration of the model's training data (one CPU core, or the GPU).

Several motions in one run (salsa 60_01, the held-out chain around its fastest
spin, the procedural spin, ballet 05_20 by default); ``PATH@START`` takes the loaded
motion's frames from START. Each row gives the wall clock and the CPU time of the thread
that ran it (``time.thread_time`` with one thread, the process's with more: on a shared
machine the wall clock also counts the other jobs' turns), both in ms per frame.

Every row runs with each ``--runtime`` (default both): ``torch``, the learned stages in
PyTorch, and ``onnx``, the motion stage and the detail generator in onnxruntime
(``animate(..., runtime="onnx")``, one intra-op thread on one torch thread), the stages
after them the same; an onnx row also gives its largest difference (m) from the torch row.
``motion`` in the stage figures is per frame computed (the preroll's too).

Only motion frames are timed (the rollout's and the simulation's preroll are
not), after a warm-up. The figures go in docs/results/BENCHMARKS.md::

    OMP_NUM_THREADS=1 python bench/speed/rollout_speed.py --sim-frames 5 --repeats 1 \
        --out out/rollout_speed_37.json
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import importlib.util
import json
import os
import platform
import time
from pathlib import Path

import numpy as np
import torch

import loosefit
from loosefit.eval.sim_runs import model_cloth, time_simulation
from loosefit.inference.stages import MOTION_ONLY, Stages
from loosefit.inference.stages.collision import CollisionConfig, collision_setting
from loosefit.motion.motions import load_motion

LEGS_ONLY = CollisionConfig(iterations=6, finish=0, whole_body=False, fast=False)  # no arms
NO_FAST_PATH = CollisionConfig(fast=False)  # collision handling without its fast path
CHAIN = "+".join(f"../shared/mocap/cmu-salsa/{n}.bvh" for n in ("60_03", "60_07", "61_03", "61_07"))
MOTIONS = [  # the whole pipeline on each of these, one command
    "../shared/mocap/cmu-salsa/60_01.bvh",
    CHAIN + "@1050",  # the held-out chain, its fastest spin (frames ~1,188-1,208) inside
    "spin",
    "../shared/mocap/cmu-ballet/05_20.bvh",
]


def pipelines(model) -> dict[str, tuple[Stages, CollisionConfig | None]]:
    """The stages timed (and the collision handling, None: the model's default): the motion
    stage alone, + detail (if any), + collision handling of the legs and trunk alone (the arms out,
    6 solves, no last projection), + collision
    handling now (the whole body, the last projection), + edge lengths (the pipeline),
    the pipeline with collision handling without its fast path and with
    ``--collision realtime``'s."""
    rows = {"motion stage": (MOTION_ONLY, None)}
    if model.detail is not None:
        rows["+ detail"] = (Stages(lengths=False, collision=False), None)
    d = "+ detail " if model.detail is not None else "+ "
    rows[d + "+ collision, legs and trunk"] = (Stages(lengths=False), LEGS_ONLY)
    rows[d + "+ collision, whole body"] = (Stages(lengths=False), None)
    rows[d + "+ lengths + collision, no fast path"] = (Stages(), NO_FAST_PATH)
    rows[d + "+ lengths + collision, realtime"] = (
        Stages(),
        collision_setting(model.collision, "realtime"),
    )
    rows[d + "+ lengths + collision (all)"] = (Stages(), None)
    return rows


def time_rollout(
    model,
    motion,
    threads: int,
    repeats: int,
    pipeline: tuple[Stages, CollisionConfig | None],
    runtime: str = "torch",
) -> tuple[dict, np.ndarray]:
    """The figures of a row and the garments (T, V, 3) of its last run."""
    stages, collision = pipeline
    with model.configured(collision):
        return _time_rollout(model, motion, threads, repeats, stages, runtime)


def _time_rollout(
    model, motion, threads: int, repeats: int, stages: Stages, runtime: str
) -> tuple[dict, np.ndarray]:
    torch.set_num_threads(threads)
    # one thread: the stages one after another; more: detail and collision on a second
    # thread beside the motion stage
    stages = dataclasses.replace(stages, overlap=threads > 1)
    # warm-up (the onnx runtime's graphs are exported here, untimed)
    model.animate(motion.slice(0, min(20, motion.num_frames)), stages=stages, runtime=runtime)
    # CPU time: the one thread's (everything runs on it), or the process's with more
    clock = time.thread_time if threads == 1 else time.process_time
    per_frame, per_frame_cpu, per_stage, per_stage_cpu = [], [], [], []
    for _ in range(repeats):
        marks = {}

        def progress(done, total, marks=marks):
            if done == total - motion.num_frames:  # the preroll is over
                marks["start"], marks["cpu"] = time.perf_counter(), clock()

        result = model.animate(motion, progress, stages=stages, runtime=runtime)
        per_frame.append((time.perf_counter() - marks["start"]) / motion.num_frames)
        per_frame_cpu.append((clock() - marks["cpu"]) / motion.num_frames)
        # the motion stage's own figure includes the preroll: per frame computed
        per_stage.append(_per_frame(result.stage_seconds, motion.num_frames, result.frames))
        per_stage_cpu.append(_per_frame(result.stage_cpu_seconds, motion.num_frames, result.frames))

    def ms(per: list[dict]) -> dict:
        return {k: 1e3 * float(np.median([d[k] for d in per])) for k in per[0]}

    s = float(np.median(per_frame))
    return {
        "threads": threads,
        "runtime": runtime,
        "seconds_per_frame": s,
        "frames_per_second": 1.0 / s,
        "cpu_seconds_per_frame": float(np.median(per_frame_cpu)),
        "ms_per_frame_of": ms(per_stage),
        "cpu_ms_per_frame_of": ms(per_stage_cpu),
    }, result.vertices


def _per_frame(seconds: dict | None, frames: int, computed: int) -> dict:
    """A result's seconds per stage, per motion frame (the motion stage's: per frame
    computed, the preroll's too)."""
    return {k: v / (computed if k == "motion" else frames) for k, v in (seconds or {}).items()}


def _name(spec: str, start_frame: int) -> str:
    """A motion spec, short: file names without folders, and where it starts."""
    path, _, at = spec.rpartition("@") if "@" in spec else (spec, "", "")
    parts = [Path(p).stem for p in path.split("+")]
    name = parts[0] if len(parts) == 1 else f"chain {parts[0]}..{parts[-1]}"
    return f"{name} from {start_frame}" + (f", frame {at} on" if at else "")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--checkpoint",
        default="checkpoints/salsa/motion.pt",
        help="a motion run's model.pt or a packaged motion.pt (its detail.pt too)",
    )
    p.add_argument(
        "--motion", nargs="+", default=MOTIONS, help="motion specs; PATH@START: from frame START on"
    )
    p.add_argument("--start-frame", type=int, default=10, help="as load_motion's")
    p.add_argument("--frames", type=int, default=300, help="rollout frames (of each motion)")
    p.add_argument("--threads", default="1", help="thread counts, e.g. 1,2 ('all': the CPUs)")
    p.add_argument(
        "--quick",
        action="store_true",
        help="only the motion stage, + detail and the whole pipeline with and "
        "without collision's fast path (not the legs-and-trunk rows)",
    )
    p.add_argument(
        "--sim-frames",
        type=int,
        default=40,
        help="simulated frames (of the same); 0: take --sim-seconds",
    )
    p.add_argument(
        "--sim-seconds",
        type=float,
        default=2.34,
        help="with --sim-frames 0: the simulation's s/frame to compare with",
    )
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument(
        "--runtime",
        default="torch,onnx",
        help="what runs the learned stages, each row with each: torch, onnx "
        "(onnxruntime; left out with a note when it is not installed)",
    )
    p.add_argument(
        "--cloth-from",
        default=None,
        help="take the cloth configuration from this "
        "dataset folder (default: the one the checkpoint records)",
    )
    p.add_argument("--out", default=None, help="also write the figures here (JSON)")
    args = p.parse_args()

    model = loosefit.load(args.checkpoint).model
    avatar = model.avatar()
    cores = os.cpu_count() or 1
    threads = sorted({cores if t == "all" else int(t) for t in args.threads.split(",")})
    motions = []
    for spec in args.motion:
        path, _, at = spec.rpartition("@") if "@" in spec else (spec, "", "")
        start = int(at) if at else 0
        m = load_motion(
            path,
            avatar,
            fps=model.fps,
            start_frame=args.start_frame,
            max_frames=None if start else args.frames,
        )
        motions.append((spec, m.slice(start, min(start + args.frames, m.num_frames))))
    motion = motions[0][1]
    runtimes = [r.strip() for r in args.runtime.split(",")]
    if "onnx" in runtimes and importlib.util.find_spec("onnxruntime") is None:
        print("onnxruntime is not installed (pip install 'loosefit[onnx]'): torch rows only")
        runtimes.remove("onnx")
    result = {
        "machine": f"{platform.processor() or platform.machine()}, {cores} CPUs, "
        f"torch {torch.__version__}",
        "date": time.strftime("%Y-%m-%d"),
        "garment_vertices": model.template.num_vertices,
        "motion": f"{Path(motions[0][0]).name} from frame {args.start_frame}",
        "rollout": [],
    }
    if "onnx" in runtimes:
        result["onnxruntime"] = importlib.import_module("onnxruntime").__version__
    for spec, m in motions:
        for label, stages in pipelines(model).items():
            if args.quick and ("legs and trunk" in label or label.endswith("body")):
                continue
            for t in threads:
                torch_garments = None
                for runtime in runtimes:
                    row, garments = time_rollout(model, m, t, args.repeats, stages, runtime)
                    row.update(
                        stages=label, motion=_name(spec, args.start_frame), frames=m.num_frames
                    )
                    if runtime == "torch":
                        torch_garments = garments
                    elif torch_garments is not None:  # the largest difference from torch's
                        gap = np.linalg.norm(garments - torch_garments, axis=-1)  # (T, V)
                        row["largest_difference_m"] = float(gap.max())
                        row["difference_p999_m"] = float(np.quantile(gap, 0.999))
                    result["rollout"].append(row)
    if torch.cuda.is_available():
        gpu = loosefit.load(args.checkpoint, device="cuda").model
        result["rollout_gpu"] = []
        for label, stages in pipelines(gpu).items():
            r, _ = time_rollout(gpu, motion, cores, args.repeats, stages)  # torch on the GPU
            r.update(stages=label, device=torch.cuda.get_device_name())
            result["rollout_gpu"].append(r)
    if args.sim_frames > 0:
        sim_motion = motion.slice(0, args.sim_frames)
        cloth = model_cloth(model, args.cloth_from)
        result["simulation"] = [time_simulation(model, avatar, sim_motion, "cpu", cloth)]
        if torch.cuda.is_available():
            result["simulation"].append(time_simulation(model, avatar, sim_motion, "cuda:0", cloth))
        sim = result["simulation"][0]["seconds_per_frame"]
    else:  # not simulated this run: the figure of docs/results/BENCHMARKS.md's last run
        sim = args.sim_seconds
        result["simulation"] = [{"seconds_per_frame": sim, "device": "cpu", "not_run": True}]
    for r in result["rollout"]:
        r["speedup_cpu"] = sim / r["seconds_per_frame"]
    sim_cpu = result["simulation"][0].get("cpu_seconds_per_frame", sim)
    for r in result["rollout"]:
        r["speedup_cpu_time"] = sim_cpu / r["cpu_seconds_per_frame"]
    full = [r for r in result["rollout"] if r["stages"] == list(pipelines(model))[-1]]
    quick = [r for r in result["rollout"] if r["stages"].endswith("realtime")]
    best = min(r["seconds_per_frame"] for r in full)
    result["speedup_cpu"] = sim / best
    print(json.dumps(result, indent=2))
    for r in result["rollout"]:
        cpu = {k: round(v, 2) for k, v in r["cpu_ms_per_frame_of"].items()}
        gap = (
            f", largest difference {r['largest_difference_m']:.1e} m"
            if ("largest_difference_m" in r)
            else ""
        )
        print(
            f"{r['motion'][:28]:>28} {r['stages']:>44} [{r['runtime']}], {r['threads']} "
            f"thread(s): {1e3 * r['seconds_per_frame']:6.1f} ms/frame (CPU "
            f"{1e3 * r['cpu_seconds_per_frame']:6.1f}; stages' CPU ms {json.dumps(cpu)}), "
            f"{r['speedup_cpu']:.0f}x faster than the simulation{gap}"
        )
    print(
        f"simulation {sim:.2f} s/frame (CPU {sim_cpu:.2f}); the whole pipeline, one thread "
        "(then with --collision realtime):"
    )
    for r in full + quick:
        if r["threads"] == 1:
            print(
                f"  {r['motion']} [{r['runtime']}]: {r['frames_per_second']:.1f} frames/s "
                f"wall, {1 / r['cpu_seconds_per_frame']:.1f} by CPU time "
                f"({1e3 * r['cpu_seconds_per_frame']:.1f} ms); {r['speedup_cpu']:.0f}x "
                f"the simulation (wall), {r['speedup_cpu_time']:.0f}x (CPU time)"
            )
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
