"""Frames per second of N characters at once.

Procedural dances of ``--frames`` frames each (the packaged salsa model, 2,352 vertices),
with ``--threads`` torch threads:

* the motion stage alone (:func:`loosefit.inference.rollout.rollout_batch`, one network call
  per frame for all N), N = ``--sizes``;
* the whole pipeline as :meth:`~loosefit.inference.animator.AnimationModel.animate_batch`
  runs it (the batched motion stage, then each character's detail, edge lengths and
  collision handling one after another), N = ``--pipeline-sizes``; and, for reference,
  the same characters one at a time through ``animate`` (whose later stages overlap the
  motion stage on a second thread);
* with ``--paper``, also the motion stage of the same networks on the paper's 9,352-vertex
  skirt (untrained weights: the cost does not depend on them).

Frames per second count every character's frames, the rollout's preroll included. Beside
the wall time: the process's CPU time (``time.process_time``, all threads) and the calling
thread's (``time.thread_time``), per frame, since the machine may be shared; the best
wall time of ``--repeats`` runs (the whole pipeline: one run). Prints the tables and the
crossover (the N past which more characters per call no longer raise frames per second);
docs/use/BATCH_INFERENCE.md quotes them::

    python bench/speed/batch_inference.py                          # CPU, 2 threads, ~10 min
    python bench/speed/batch_inference.py --device cuda --paper    # on a GPU
    python bench/speed/batch_inference.py --runtime onnx --collision realtime --threads 1
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import torch

import loosefit
from loosefit.api import motion_for
from loosefit.inference.model_common import RUNTIMES
from loosefit.inference.rollout import MotionStage, rollout_batch
from loosefit.inference.stages import MOTION_ONLY, Stages
from loosefit.inference.stages.collision import COLLISION_SETTINGS


def paper_scale(model):
    """The packaged networks' configuration on the paper's 9,352-vertex skirt."""
    from loosefit.fitting.place import fit_skirt
    from loosefit.garment.skirt import SkirtConfig
    from loosefit.model.generative import GarmentGenerativeModel
    from loosefit.model.motion_encoder import DynamicMotionEncoder

    m = model.model
    skirt = fit_skirt(m.avatar(), SkirtConfig.preset("paper", "flared"))
    gen = GarmentGenerativeModel(skirt, m.generative.config)
    enc = DynamicMotionEncoder(gen, m.encoder.num_features, m.encoder.config)
    return gen.eval(), enc.eval(), torch.from_numpy(skirt.vertices).float()


def clock(run, repeats: int, device: str) -> tuple[dict, object]:
    """The best wall seconds of ``repeats`` calls of ``run()``, with that call's CPU seconds
    (process and calling thread), and its result."""
    best, out = None, None
    for _ in range(repeats):
        w, pr, th = time.perf_counter(), time.process_time(), time.thread_time()
        out = run()
        if device.startswith("cuda"):
            torch.cuda.synchronize()
        t = {
            "wall": time.perf_counter() - w,
            "process": time.process_time() - pr,
            "thread": time.thread_time() - th,
        }
        if best is None or t["wall"] < best["wall"]:
            best = t
    return best, out


def row(what: str, n: int, frames: int, t: dict, stage_seconds: dict | None = None) -> dict:
    """One table row: frames/s (wall) and ms per frame of wall, process and thread time."""
    r = {
        "what": what,
        "N": n,
        "frames": frames,
        "frames_per_second": frames / t["wall"],
        **{f"ms_{k}": 1e3 * v / frames for k, v in t.items()},
    }
    if stage_seconds:
        r["ms_stage"] = {k: 1e3 * v / frames for k, v in stage_seconds.items()}
    return r


def crossover(rows: list[dict]) -> str:
    """Where more characters per call stop raising frames per second."""
    fps = [(r["N"], r["frames_per_second"]) for r in rows]
    peak_n, peak = max(fps, key=lambda x: x[1])
    one = dict(fps).get(1)
    after = [(n, f) for n, f in fps if n > peak_n]
    text = f"peak {peak:,.0f} frames/s at N = {peak_n}"
    if one:
        text += f" ({peak / one:.1f}x N = 1)"
    if after:
        text += "; beyond it " + ", ".join(f"N = {n}: {f:,.0f}" for n, f in after)
    return text


def table(rows: list[dict], stage_column: bool = False) -> list[str]:
    head = "| what | N | frames/s (wall) | ms/frame wall | ms/frame process CPU "
    head += "| ms/frame thread CPU |"
    head += " ms/frame per stage (busy) |" if stage_column else ""
    lines = [head, "|---|---:|---:|---:|---:|---:|" + ("---|" if stage_column else "")]
    for r in rows:
        line = (
            f"| {r['what']} | {r['N']} | {r['frames_per_second']:,.0f} | {r['ms_wall']:.2f} "
            f"| {r['ms_process']:.2f} | {r['ms_thread']:.2f} |"
        )
        if stage_column:
            stages = r.get("ms_stage") or {}
            line += " " + ", ".join(f"{k} {v:.2f}" for k, v in stages.items()) + " |"
        lines.append(line)
    return lines


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="1,2,4,8,16,32,64", help="N for the motion stage")
    ap.add_argument("--pipeline-sizes", default="1,8,32", help="N for the whole pipeline")
    ap.add_argument("--frames", type=int, default=60, help="motion frames per character")
    ap.add_argument("--threads", type=int, default=2, help="torch threads (0: torch's default)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--paper", action="store_true", help="also the paper's resolution")
    ap.add_argument("--out", default=None, help="also write the rows here (JSON)")
    ap.add_argument(
        "--runtime",
        choices=RUNTIMES,
        default="torch",
        help="what runs the learned stages (onnx: the packaged model's motion "
        "stage rows and the whole pipeline)",
    )
    ap.add_argument(
        "--collision",
        choices=COLLISION_SETTINGS,
        default="full",
        help="the whole pipeline's collision handling",
    )
    args = ap.parse_args()

    if args.threads:
        torch.set_num_threads(args.threads)
    load_before = os.getloadavg()
    model = loosefit.load(device=args.device)
    m = model.model
    avatar = m.avatar()
    sizes = [int(n) for n in args.sizes.split(",")]
    whole = [int(n) for n in args.pipeline_sizes.split(",") if n]
    dances = [
        motion_for("dance:4", avatar, model.fps, args.frames, seed=i)
        for i in range(max(sizes + whole))
    ]
    scales = {"motion stage (2,352 vertices)": (m.generative, m.encoder, m.rest_state)}
    if args.paper:
        g, e, rest = paper_scale(model)
        scales["motion stage (paper, 9,352 vertices)"] = (
            g.to(args.device),
            e.to(args.device),
            rest.to(args.device),
        )
    motion_rows = []
    for name, (gen, enc, rest) in scales.items():

        def motion_stage(n, g=gen, e=enc, r=rest, packaged=gen is m.generative):
            if packaged and args.runtime == "onnx":
                return m.animate_batch(dances[:n], stages=MOTION_ONLY, runtime="onnx")
            stage = MotionStage(g, e, r, m.floor_height, m.rollout_config)
            return rollout_batch(stage, dances[:n])

        motion_stage(1)  # warm-up (the onnx runtime's graphs exported)
        for n in sizes:
            t, res = clock(lambda n=n, f=motion_stage: f(n), args.repeats, args.device)
            motion_rows.append(row(name, n, sum(r.frames for r in res), t))
            print(
                f"{name}: N={n}: {motion_rows[-1]['frames_per_second']:,.0f} frames/s", flush=True
            )
    pipeline_rows = []
    how = {"runtime": args.runtime, "collision": args.collision}
    m.animate_batch(dances[:1], stages=Stages(), **how)  # warm-up (the collider's first build)
    for n in whole:
        t, res = clock(lambda n=n: m.animate_batch(dances[:n], **how), 1, args.device)
        busy = {}
        for r in res:
            for k, v in (r.stage_seconds or {}).items():
                busy[k] = busy.get(k, 0.0) + (v if k != "motion" else 0.0)
        busy["motion"] = res[0].stage_seconds["motion"]  # shared by the batch
        pipeline_rows.append(
            row("animate_batch (whole pipeline)", n, sum(r.frames for r in res), t, busy)
        )
        print(
            f"animate_batch: N={n}: {pipeline_rows[-1]['frames_per_second']:,.0f} frames/s",
            flush=True,
        )
    one_by_one = whole and min(max(whole), 8)
    if one_by_one:
        t, res = clock(lambda: [m.animate(d, **how) for d in dances[:one_by_one]], 1, args.device)
        pipeline_rows.append(
            row("animate, one character after another", one_by_one, sum(r.frames for r in res), t)
        )
    dev = (
        torch.cuda.get_device_name()
        if args.device.startswith("cuda")
        else f"{platform.machine()}, {torch.get_num_threads()} torch threads"
    )
    load = ", ".join(f"{a:.1f}" for a in (*load_before, *os.getloadavg()))
    lines = [
        f"`bench/speed/batch_inference.py` on {dev}, torch {torch.__version__}; "
        f"{args.frames} motion frames per character (+ the preroll); runtime "
        f"{args.runtime}, {args.collision} collision handling; load average "
        f"(1, 5, 15 min) before and after: {load}",
        "",
        *table(motion_rows),
        "",
    ]
    for name in scales:
        lines.append(f"- {name}: {crossover([r for r in motion_rows if r['what'] == name])}")
    if pipeline_rows:
        batched = [r for r in pipeline_rows if r["what"].startswith("animate_batch")]
        lines += [
            "",
            *table(pipeline_rows, stage_column=True),
            "",
            f"- whole pipeline: {crossover(batched)}",
        ]
    print("\n".join(lines))
    if args.out:
        Path(args.out).write_text(
            json.dumps(
                {
                    "device": dev,
                    "frames": args.frames,
                    "motion": motion_rows,
                    "pipeline": pipeline_rows,
                },
                indent=1,
            )
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
