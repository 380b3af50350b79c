"""The exported ONNX runtime against the PyTorch rollout, one thread each, in one run.

For the packaged model (or ``--checkpoint``): the graph of ``loosefit export-model`` with
and without the detail stage, rolled out by the reference loop
(:func:`loosefit.inference.onnx.runtime.rollout_onnx`, onnxruntime with
``intra_op_num_threads=1``), and the PyTorch rollout of the same stages
(``torch.set_num_threads(1)``, no overlap), on one motion. Every frame computed counts
(the preroll's too, in both). Wall time is the best of ``--repeats``; beside it the
calling thread's CPU time (``time.thread_time``) and the process's (``time.process_time``)
of that run, since the machine may be shared. Also the largest difference of the garments
(m). docs/results/BENCHMARKS.md and docs/use/ENGINE_EXPORT.md quote the table::

    OMP_NUM_THREADS=1 python bench/speed/onnx_speed.py --motion dance:12 --frames 300

``--batch 1,8,32`` also steps B characters per call of the graph (with the detail stage).
"""

from __future__ import annotations

import argparse
import platform
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

import loosefit
from loosefit.api import motion_for
from loosefit.inference.onnx.export import OnnxExportConfig, export_onnx
from loosefit.inference.onnx.runtime import OnnxRuntime, rollout_onnx
from loosefit.inference.stages import MOTION_ONLY, Stages

WITH_DETAIL = Stages(lengths=False, collision=False, overlap=False)


def timed(run, repeats: int) -> tuple[dict, np.ndarray]:
    """The best wall time of ``repeats`` calls of ``run()`` and that call's CPU times."""
    best, out = None, None
    for _ in range(repeats):
        w, th, pr = time.perf_counter(), time.thread_time(), time.process_time()
        out = run()
        w, th, pr = time.perf_counter() - w, time.thread_time() - th, time.process_time() - pr
        if best is None or w < best["wall"]:
            best = {"wall": w, "thread": th, "process": pr}
    return best, out


def print_batches(args, model, frames: int) -> None:
    """The graph with the detail stage stepping B characters at once (B procedural dances),
    one thread: frames per second counting every character's frames, preroll included."""
    from loosefit.inference.timeline import rollout_timeline

    sizes = [int(b) for b in args.batch.split(",")]
    rc = model.rollout_config
    lines = [
        (
            rollout_timeline(
                motion_for("dance:12", model.avatar(), model.fps, frames, seed=i),
                model.floor_height,
                rc.warm_frames,
                rc.blend_seconds,
            )
        )
        for i in range(max(sizes))
    ]
    rot = np.stack([r for r, _, _ in lines]).astype(np.float32)  # (B, P + T, J, 3, 3)
    root = np.stack([q for _, q, _ in lines]).astype(np.float32)  # (B, P + T, 3)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "detail.onnx"
        export_onnx(model, path, OnnxExportConfig(detail=model.detail is not None))
        runtime = OnnxRuntime(path, threads=1)

        def run(B: int) -> None:
            state = runtime.initial_state(B)
            for t in range(rot.shape[1]):
                _, state = runtime.step(rot[:B, t], root[:B, t], state, start=t == 0)

        print(
            "| characters B | frames/s (wall) | ms/frame wall | ms/frame thread CPU | "
            "ms/frame process CPU |"
        )
        print("|---:|---:|---:|---:|---:|")
        run(1)  # warm-up
        for B in sizes:
            t, _ = timed(lambda B=B: run(B), args.repeats)
            n = B * rot.shape[1]
            print(
                f"| {B} | {n / t['wall']:.0f} | {1e3 * t['wall'] / n:.2f} | "
                f"{1e3 * t['thread'] / n:.2f} | {1e3 * t['process'] / n:.2f} |",
                flush=True,
            )
    print()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", default="checkpoints/salsa/motion.pt")
    ap.add_argument("--motion", default="dance:12", help="a file or a procedural move")
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--batch", default="", help="also B characters per call, e.g. 1,8,32")
    args = ap.parse_args()

    torch.set_num_threads(1)
    model = loosefit.load(args.checkpoint).model
    motion = motion_for(args.motion, model.avatar(), model.fps, args.frames, seed=args.seed)
    total = None
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for label, stages, detail in (
            ("motion stage", MOTION_ONLY, False),
            ("motion stage + detail", WITH_DETAIL, True),
        ):
            if detail and model.detail is None:
                continue
            path = Path(tmp) / f"{'detail' if detail else 'motion'}.onnx"
            export_onnx(model, path, OnnxExportConfig(detail=detail))
            runtime = OnnxRuntime(path, threads=1)
            model.animate(motion.slice(0, 10), stages=stages)  # warm-up
            rollout_onnx(runtime, motion.slice(0, 10))
            t_torch, ref = timed(lambda s=stages: model.animate(motion, stages=s), args.repeats)
            t_onnx, got = timed(lambda r=runtime: rollout_onnx(r, motion), args.repeats)
            total = ref.frames
            gap = float(np.linalg.norm(got - ref.vertices, axis=-1).max())
            for what, t in (("PyTorch", t_torch), ("onnxruntime", t_onnx)):
                ms = {k: 1e3 * v / total for k, v in t.items()}
                rows.append(
                    (label, what, total / t["wall"], ms["wall"], ms["thread"], ms["process"], gap)
                )
            print(f"{label}: largest difference {gap:.2e} m", flush=True)
    print(
        f"\n{platform.machine()}, torch {torch.__version__}, onnxruntime "
        f"{__import__('onnxruntime').__version__}, 1 thread each; {motion.name}, "
        f"{motion.num_frames} frames + {total - motion.num_frames} of preroll\n"
    )
    if args.batch:
        print_batches(args, model, motion.num_frames)
    print(
        "| stages | runtime | frames/s (wall) | ms/frame wall | ms/frame thread CPU | "
        "ms/frame process CPU | largest difference (m) |"
    )
    print("|---|---|---:|---:|---:|---:|---:|")
    for label, what, fps, wall, thread, proc, gap in rows:
        print(
            f"| {label} | {what} | {fps:.0f} | {wall:.2f} | {thread:.2f} | {proc:.2f} | {gap:.1e} |"
        )


if __name__ == "__main__":
    main()
