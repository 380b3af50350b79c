"""The engine tier against the full pipeline and the simulation: speed and quality, one command.

Per frame on one CPU thread (``time.thread_time``: this thread's CPU, the machine being
shared), for 1, 16 and 256 characters:

* ``full pipeline``: ``animate`` (``animate_batch`` for N > 1), PyTorch, full collision;
* ``onnx, realtime collision``: the same with ``runtime="onnx", collision="realtime"``;
* ``engine tier``: the exported graph (:mod:`loosefit.inference.engine.export`) through
  the reference loop (:mod:`loosefit.inference.engine.runtime`), with the capsule push-out
  in the graph, and without it (the graph exported with ``capsules=False``);
* the simulation of the same skirt on the same machine (Newton, one thread), for the
  speed-up.

Quality on held-out clips of the data set (default: the held-out chain and the ballet clip
05_10) against the simulation, with :func:`loosefit.eval.stage_account.clip_reference`'s
measures: RMSE, hem flare error over the 61 frames around the fastest turn, median signed
edge change, share of vertices inside the body; and the engine tier's graph against its
PyTorch model (max difference over the clip).

    OMP_NUM_THREADS=1 python bench/speed/engine_tier.py --out docs/results/ENGINE_TIER.md

Writes the Markdown table and the figures as JSON in bench/figures/.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

import loosefit
from loosefit.api import pretrained_checkpoint
from loosefit.data.format import DatasetReader
from loosefit.eval.sim_runs import model_cloth, time_simulation
from loosefit.eval.stage_account import clip_reference
from loosefit.inference.engine.export import EngineExportConfig, EngineStep, export_engine
from loosefit.inference.engine.model import engine_path_of, load_engine, rollout_engine
from loosefit.inference.engine.runtime import EngineRuntime, rollout_engine_onnx
from loosefit.inference.timeline import rollout_timeline
from loosefit.motion.motions import load_motion

# the figures of a page docs/X.md as JSON: bench/figures/X.json
FIGURES = Path(__file__).resolve().parents[1] / "figures"


MEASURES = (
    "rmse_cm",
    "flare_turn_error",
    "flare_turn_ratio",
    "edge_change_p50",
    "inside_whole_mean",
)


def time_full(model, motion, n: int, runtime: str, collision: str) -> float:
    """CPU ms per character per motion frame of the pipeline on ``n`` copies of ``motion``."""
    t0 = time.thread_time()
    if n == 1:
        model.animate(motion, runtime=runtime, collision=collision)
    else:
        model.animate_batch([motion] * n, runtime=runtime, collision=collision)
    return 1e3 * (time.thread_time() - t0) / (n * motion.num_frames)


def time_engine(runtime: EngineRuntime, motion, n: int, floor: float, repeats: int = 3) -> float:
    """CPU ms per character per frame of the graph's step for ``n`` characters (the best of
    ``repeats`` passes over the motion's timeline, every frame counted)."""
    rot, root, _ = rollout_timeline(motion, floor, 5, 0.5)
    rot = np.ascontiguousarray(np.repeat(rot[:, None], n, 1), np.float32)  # (T, n, J, 3, 3)
    root = np.ascontiguousarray(np.repeat(root[:, None], n, 1), np.float32)
    best = float("inf")
    for _ in range(repeats):
        state = runtime.initial_state(n)
        t0 = time.thread_time()
        for t in range(len(rot)):
            _, state = runtime.step(rot[t], root[t], state, start=t == 0)
        best = min(best, (time.thread_time() - t0) / (n * len(rot)))
    return 1e3 * best


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", default="datasets/dance")
    p.add_argument("--clips", default="chain_60_03_60_07_61_03_61_07,05_10")
    p.add_argument("--checkpoint", default=None, help="motion.pt (default: the pretrained)")
    p.add_argument("--engine", default=None, help="engine.pt (default: beside --checkpoint)")
    p.add_argument("--batch", default="1,16,256")
    p.add_argument("--frames", type=int, default=60, help="frames of the speed motion")
    p.add_argument(
        "--full-frames",
        default="60,10,3",
        help="motion frames the full pipeline is timed on, per --batch",
    )
    p.add_argument("--sim-frames", type=int, default=3)
    p.add_argument("--out", default="docs/results/ENGINE_TIER.md")
    p.add_argument("--machine", default=platform.node(), help="the machine's name in the doc")
    args = p.parse_args()
    torch.set_num_threads(1)
    checkpoint = Path(args.checkpoint) if args.checkpoint else pretrained_checkpoint()
    model = loosefit.load(checkpoint).model
    engine = load_engine(args.engine or engine_path_of(checkpoint))
    reader = DatasetReader(args.data)
    tmp = Path(tempfile.mkdtemp())
    export_engine(engine, tmp / "engine.onnx", EngineExportConfig(check_frames=0))
    export_engine(engine, tmp / "free.onnx", EngineExportConfig(capsules=False, check_frames=0))
    graphs = {
        "engine tier": EngineRuntime(tmp / "engine.onnx"),
        "engine tier, no push-out": EngineRuntime(tmp / "free.onnx"),
    }
    result = {
        "machine": f"{args.machine}, {os.cpu_count()} CPUs, torch {torch.__version__}",
        "date": time.strftime("%Y-%m-%d"),
        "checkpoint": str(checkpoint),
        "engine": str(engine.path),
        "speed": {},
        "quality": {},
    }

    # 1. speed, one thread
    motion = load_motion("dance:12", model.avatar(), max_frames=args.frames)
    batches = [int(b) for b in args.batch.split(",")]
    full_frames = [int(f) for f in args.full_frames.split(",")]
    model.animate(motion.slice(0, 10), runtime="onnx")  # the onnx graphs exported, untimed
    for n, frames in zip(batches, full_frames, strict=True):
        m = motion.slice(0, frames)
        row = {
            "full pipeline": time_full(model, m, n, "torch", "full"),
            "onnx, realtime collision": time_full(model, m, n, "onnx", "realtime"),
        }
        for label, rt in graphs.items():
            row[label] = time_engine(rt, motion, n, engine.floor_height)
        result["speed"][n] = row
        print(n, {k: round(v, 4) for k, v in row.items()}, flush=True)
    sim = time_simulation(
        model,
        model.avatar(),
        motion.slice(0, args.sim_frames),
        "cpu",
        model_cloth(model, args.data),
    )
    result["simulation_ms_per_frame"] = 1e3 * sim["cpu_seconds_per_frame"]
    print("simulation", result["simulation_ms_per_frame"], flush=True)

    # 2. quality on held-out clips
    step = EngineStep(engine, *_capsules(engine)).eval()
    for name in args.clips.split(","):
        seq = reader.read(name)
        measure, turn, window = clip_reference(model, seq)
        rows = {
            "simulation": np.asarray(seq.garment_vertices, np.float32),
            "full pipeline": model.animate(seq.motion).vertices,
            "onnx, realtime collision": model.animate(
                seq.motion, runtime="onnx", collision="realtime"
            ).vertices,
            "engine tier": rollout_engine_onnx(graphs["engine tier"], seq.motion),
            "engine tier, no push-out": rollout_engine_onnx(
                graphs["engine tier, no push-out"], seq.motion
            ),
        }
        torch_engine = rollout_engine(engine, seq.motion, collide=step)
        clip = {
            "frames": seq.motion.num_frames,
            "turn": turn,
            "engine_onnx_vs_torch_m": float(np.abs(rows["engine tier"] - torch_engine).max()),
            "rows": {},
        }
        for label, x in rows.items():
            figures = measure(x)
            clip["rows"][label] = {k: figures[k] for k in MEASURES}
            print(name, label, {k: round(v, 4) for k, v in clip["rows"][label].items()}, flush=True)
        result["quality"][name] = clip
    out = Path(args.out)
    (FIGURES / f"{out.stem}.json").write_text(json.dumps(result, indent=1) + "\n")
    out.write_text(markdown(result))
    print(out.read_text())


def _capsules(engine):
    from loosefit.body.capsules import avatar_capsules
    from loosefit.inference.engine.export import skeleton_record

    avatar = engine.avatar()
    return avatar_capsules(avatar), skeleton_record(avatar)


def markdown(r: dict) -> str:
    sim = r["simulation_ms_per_frame"]
    lines = [
        f"# The engine tier against the full pipeline ({r['machine']}, {r['date']})",
        "",
        "Written by `OMP_NUM_THREADS=1 python bench/speed/engine_tier.py`. CPU ms per character "
        "per frame on one thread; the simulation of the same skirt: "
        f"{sim:.0f} ms a frame on the same machine in the same run.",
        "",
        "| runtime | " + " | ".join(f"N = {n}" for n in r["speed"]) + " | x simulation (N = 1) |",
        "|---|" + "---:|" * (len(r["speed"]) + 1),
    ]
    labels = list(next(iter(r["speed"].values())))
    for label in labels:
        cells = [f"{row[label]:.4f}" for row in r["speed"].values()]
        first = next(iter(r["speed"].values()))[label]
        lines.append(f"| {label} | " + " | ".join(cells) + f" | {sim / first:,.0f} |")
    lines += [
        "",
        "Quality against the simulation (flare error: the mean of |flare / "
        "flare_sim - 1| over the 61 frames around the fastest turn; edge change: the "
        "median signed change of the edge lengths against rest):",
        "",
    ]
    head = (
        "| clip | runtime | RMSE cm | flare error at turn | flare ratio at turn | "
        "edge change p50 | inside body |"
    )
    lines += [head, "|---|---|---:|---:|---:|---:|---:|"]
    for name, clip in r["quality"].items():
        for label, q in clip["rows"].items():
            lines.append(
                f"| {name} | {label} | {q['rmse_cm']:.2f} | {q['flare_turn_error']:.1%} | "
                f"{q['flare_turn_ratio']:.3f} | {q['edge_change_p50']:+.2%} | "
                f"{q['inside_whole_mean']:.2%} |"
            )
    lines += [""]
    for name, clip in r["quality"].items():
        worst = clip["engine_onnx_vs_torch_m"]
        lines.append(
            f"- {name}: the engine tier's graph against its PyTorch model, "
            f"{clip['frames']} frames: at most {worst:.2g} m."
        )
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
