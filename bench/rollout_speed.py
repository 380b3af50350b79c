"""Learned rollout against the simulation that made its data: seconds per frame, same garment.

Times, in one run, on the same garment and the same motion:

* the rollout of a trained model (``loosefit animate``'s work: motion features,
  the encoder, the frozen decoders, one frame after another), then with the detail
  stage (paper 3.4, when the checkpoint has one packaged beside it) and with
  collision handling (3.5): the whole pipeline, each stage's milliseconds per frame
  apart, with 1 CPU thread and with all of them, and on the GPU when there is one;
* Newton's VBD simulation of that garment on that motion, with the cloth
  configuration of the model's training data (one CPU core, or the GPU).

Only motion frames are timed (the rollout's and the simulation's preroll are
not), after a warm-up. The figures go in docs/BENCHMARKS.md::

    python bench/rollout_speed.py --checkpoint runs/motion-cpu-ps/model.pt \
        --motion ../shared/mocap/cmu-salsa/60_01.bvh --frames 300 --sim-frames 40
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import time
from pathlib import Path

import numpy as np
import torch

from loosefit.body.motions import load_motion
from loosefit.geometry.collision import CollisionConfig
from loosefit.inference.animator import load_pipeline
from loosefit.model.rollout import MOTION_ONLY, Stages

BEFORE_34 = CollisionConfig(iterations=6, finish=0, whole_body=False)  # as before issue 34


def pipelines(model) -> dict[str, tuple[Stages, CollisionConfig | None]]:
    """The stages timed (and the collision handling, None: the model's default): the motion
    stage alone, + detail (if any), + collision handling as before issue 34, + collision
    handling now (the whole body, the last projection), + edge lengths (the pipeline)."""
    rows = {"motion stage": (MOTION_ONLY, None)}
    if model.detail is not None:
        rows["+ detail"] = (Stages(lengths=False, collision=False), None)
    d = "+ detail " if model.detail is not None else "+ "
    rows[d + "+ collision, before issue 34"] = (Stages(lengths=False), BEFORE_34)
    rows[d + "+ collision, whole body"] = (Stages(lengths=False), None)
    rows[d + "+ lengths + collision (all)"] = (Stages(), None)
    return rows


def time_rollout(model, motion, threads: int, repeats: int,
                 pipeline: tuple[Stages, CollisionConfig | None]) -> dict:  # fmt: skip
    stages, collision = pipeline
    with model.configured(collision):
        return _time_rollout(model, motion, threads, repeats, stages)


def _time_rollout(model, motion, threads: int, repeats: int, stages: Stages) -> dict:
    torch.set_num_threads(threads)
    # one thread: the stages one after another; more: detail and collision on a second
    # thread beside the motion stage
    stages = dataclasses.replace(stages, overlap=threads > 1)
    model.animate(motion.slice(0, min(20, motion.num_frames)), stages=stages)  # warm-up
    per_frame, per_stage = [], []
    for _ in range(repeats):
        marks = {}

        def progress(done, total, marks=marks):
            if done == total - motion.num_frames:  # the preroll is over
                marks["start"] = time.perf_counter()

        result = model.animate(motion, progress, stages=stages)
        per_frame.append((time.perf_counter() - marks["start"]) / motion.num_frames)
        per_stage.append(
            {k: v for k, v in (result.stage_seconds or {}).items() if k != "motion"}
        )  # fmt: skip (motion's includes the preroll)
    s = float(np.median(per_frame))
    ms = {k: 1e3 * float(np.median([d[k] for d in per_stage])) / motion.num_frames
          for k in per_stage[0]}  # fmt: skip
    return {"threads": threads, "seconds_per_frame": s, "frames_per_second": 1.0 / s,
            "ms_per_frame_of": ms}  # fmt: skip


def time_simulation(model, avatar, motion, device: str, cloth: dict) -> dict:
    from loosefit.sim.cloth import ClothConfig, simulate

    cloth = dict(cloth)
    cloth["device"] = device
    marks = {}

    def progress(done, total):
        if done == total - motion.num_frames:
            marks["start"] = time.perf_counter()

    simulate(avatar, model.template, motion, ClothConfig(**cloth), progress=progress)
    s = (time.perf_counter() - marks["start"]) / motion.num_frames
    return {"device": device, "seconds_per_frame": s}


def model_cloth(model, dataset: str | None) -> dict:
    """The cloth configuration of the model's training data (its checkpoint's, or a dataset's)."""
    if dataset:
        return json.loads((Path(dataset) / "manifest.json").read_text())["config"]["cloth"]
    data = torch.load(model.path, map_location="cpu", weights_only=False)
    if not data.get("cloth"):
        raise SystemExit(f"{model.path} records no cloth configuration; pass --cloth-from DATASET")
    return data["cloth"]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--checkpoint",
        default="checkpoints/salsa/motion.pt",
        help="a motion run's model.pt or a packaged motion.pt (its detail.pt too)",
    )
    p.add_argument("--motion", default="../shared/mocap/cmu-salsa/60_01.bvh")
    p.add_argument("--start-frame", type=int, default=10)
    p.add_argument("--frames", type=int, default=300, help="rollout frames")
    p.add_argument("--sim-frames", type=int, default=40,
                   help="simulated frames (of the same); 0: take --sim-seconds")  # fmt: skip
    p.add_argument(
        "--sim-seconds",
        type=float,
        default=2.34,
        help="with --sim-frames 0: the simulation's s/frame to compare with",
    )
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument(
        "--cloth-from",
        default=None,
        help="take the cloth configuration from this "
        "dataset folder (default: the one the checkpoint records)",
    )
    p.add_argument("--out", default=None, help="also write the figures here (JSON)")
    args = p.parse_args()

    model = load_pipeline(args.checkpoint)
    avatar = model.avatar()
    motion = load_motion(args.motion, avatar, fps=model.fps, start_frame=args.start_frame,
                         max_frames=args.frames)  # fmt: skip
    cores = os.cpu_count() or 1
    result = {
        "machine": f"{platform.processor() or platform.machine()}, {cores} CPUs, "
        f"torch {torch.__version__}",
        "garment_vertices": model.template.num_vertices,
        "motion": f"{Path(args.motion).name} from frame {args.start_frame}",
        "rollout": [
            dict(time_rollout(model, motion, t, args.repeats, stages), stages=label)
            for label, stages in pipelines(model).items()
            for t in sorted({1, cores})
        ],  # fmt: skip
    }
    if torch.cuda.is_available():
        gpu = load_pipeline(args.checkpoint, device="cuda")
        result["rollout_gpu"] = []
        for label, stages in pipelines(gpu).items():
            r = time_rollout(gpu, motion, cores, args.repeats, stages)
            r.update(stages=label, device=torch.cuda.get_device_name())
            result["rollout_gpu"].append(r)
    if args.sim_frames > 0:
        sim_motion = motion.slice(0, args.sim_frames)
        cloth = model_cloth(model, args.cloth_from)
        result["simulation"] = [time_simulation(model, avatar, sim_motion, "cpu", cloth)]
        if torch.cuda.is_available():
            result["simulation"].append(time_simulation(model, avatar, sim_motion, "cuda:0",
                                                        cloth))  # fmt: skip
        sim = result["simulation"][0]["seconds_per_frame"]
    else:  # not simulated this run: the figure of docs/BENCHMARKS.md's last run
        sim = args.sim_seconds
        result["simulation"] = [{"seconds_per_frame": sim, "device": "cpu", "not_run": True}]
    for r in result["rollout"]:
        r["speedup_cpu"] = sim / r["seconds_per_frame"]
    full = [r for r in result["rollout"] if r["stages"] == list(pipelines(model))[-1]]
    best = min(r["seconds_per_frame"] for r in full)
    result["speedup_cpu"] = sim / best
    print(json.dumps(result, indent=2))
    for r in result["rollout"]:
        print(
            f"{r['stages']:>40}, {r['threads']} thread(s): {1e3 * r['seconds_per_frame']:6.1f} "
            f"ms/frame {json.dumps({k: round(v, 2) for k, v in r['ms_per_frame_of'].items()})}"
            f", {r['speedup_cpu']:.0f}x faster than the simulation"
        )
    print(f"simulation {sim:.2f} s/frame; the whole pipeline is {sim / best:.0f}x faster per frame")
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
