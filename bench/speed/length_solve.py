"""The edge-length stage's solve on one core: the dense inverse it had against the banded one.

:class:`~loosefit.inference.stages.lengths.LengthRestorer`'s rounds solve one fixed system of the
garment's free vertices for every coordinate of every frame of a chunk. Before the fast path
that was one product with its dense float32 inverse; now it is the banded Cholesky
factor taken by blocks (:mod:`loosefit.geometry.banded`). On the committed salsa
pipeline this times, with one thread and by the CPU time of that thread
(``time.thread_time``: the machine is shared):

* ``restore_numpy`` on 64-frame chunks (the rollout's) of the stage's real input (the
  pipeline without edge lengths and collision handling on salsa 60_01), the dense rounds
  (as before, reproduced here from the restorer's system) and the committed ones;
* their largest difference from each other and from the same rounds in float64 with an
  exact (SuperLU) solve;
* the whole pipeline's ``lengths`` stage (``stage_cpu_seconds``, overlap off) with the
  dense rounds swapped in and as committed.

    OMP_NUM_THREADS=1 python bench/speed/length_solve.py [--repeats 5] [--out out/length_solve.json]

Figures (dev-cpu, 2 cores shared, 2026-11-26) in docs/design/notes/BENCHMARKS_HISTORY.md.
"""

from __future__ import annotations

import argparse
import json
import time
from datetime import date
from pathlib import Path

import numpy as np
import torch

import loosefit
from loosefit.inference.stages import Stages
from loosefit.motion.motions import load_motion
from loosefit.train.common import machine

CHUNK = 64  # frames a call (the rollout's chunk)


def dense_inverse(restorer) -> np.ndarray:
    """(Vf, Vf) float32: the inverse of the restorer's system, as kept before the fast path."""
    bf_t = restorer._bf_t  # (Vf, E)
    system = (bf_t @ bf_t.T).toarray() + restorer.config.tie * np.eye(bf_t.shape[0])
    return np.linalg.inv(system).astype(np.float32)


def dense_rounds(restorer, x: np.ndarray, inverse: np.ndarray | None) -> np.ndarray:
    """(B, V, 3) -> (B, V, 3): the rounds as before the fast path, all float32, solving for the
    positions with the dense float32 ``inverse`` (None: all float64 with the exact SuperLU
    solve, the reference)."""
    cfg = restorer.config
    exact = inverse is None
    dt = np.float64 if exact else np.float32
    inc = restorer._inc32.astype(dt)  # (E, V), vertices in the restorer's order
    order, Vf = restorer._order, len(restorer.free)
    B, V, _ = x.shape
    cols = np.asarray(x, dt).transpose(1, 0, 2)[order].reshape(V, B * 3)
    x0f = cols[:Vf].copy()
    held_part = restorer._bh.astype(dt) @ cols[Vf:]  # (E, B*3)
    bf_t = restorer._bf_t.astype(dt)
    rest = restorer._rest32.astype(dt)[:, :, None]  # (E, 1, 1)
    cur = cols
    for _ in range(cfg.iterations):
        d = (inc @ cur).reshape(-1, B, 3)
        sq = d * d
        length = np.maximum(np.sqrt(sq[..., 0:1] + sq[..., 1:2] + sq[..., 2:3]), 1e-12)
        scale = rest / length
        if cfg.compression_only:
            scale = np.maximum(scale, 1.0)
        rhs = bf_t @ ((d * scale).reshape(-1, B * 3) - held_part) + dt(cfg.tie) * x0f
        cur[:Vf] = restorer._lu.solve(rhs) if exact else inverse @ rhs
    out = np.empty((V, B, 3), dt)
    out[order] = cur.reshape(V, B, 3)
    return out.transpose(1, 0, 2)


def cpu_ms(fn, chunks, repeats: int) -> float:
    """The best over ``repeats`` of the thread's CPU ms a frame of ``fn`` over all chunks."""
    fn(chunks[0])  # warm-up
    best = np.inf
    for _ in range(repeats):
        t0 = time.thread_time()
        for c in chunks:
            fn(c)
        best = min(best, time.thread_time() - t0)
    return 1e3 * best / sum(len(c) for c in chunks)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--checkpoint", default="checkpoints/salsa/motion.pt")
    ap.add_argument("--motion", default="../shared/mocap/cmu-salsa/60_01.bvh")
    ap.add_argument("--frames", type=int, default=150)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    torch.set_num_threads(1)
    model = loosefit.load(args.checkpoint).model
    motion = load_motion(
        args.motion, model.avatar(), fps=model.fps, start_frame=10, max_frames=args.frames
    )
    restorer = model.restorer(Stages())
    # the stage's input: the pipeline up to edge lengths
    frames = model.animate(motion, stages=Stages(lengths=False, collision=False)).vertices
    frames = np.asarray(frames, np.float32)  # (T, V, 3)
    chunks = [frames[s : s + CHUNK] for s in range(0, len(frames), CHUNK)]

    inverse = dense_inverse(restorer)

    def dense(x):
        return dense_rounds(restorer, x, inverse)

    now = np.concatenate([restorer.restore_numpy(c) for c in chunks])
    before = np.concatenate([dense(c) for c in chunks])
    exact = np.concatenate([dense_rounds(restorer, c, None) for c in chunks])
    result = {
        "machine": machine("cpu"),
        "date": date.today().isoformat(),
        "motion": args.motion,
        "frames": len(frames),
        "free vertices": len(restorer.free),
        "bandwidth": restorer.banded.bandwidth if restorer.banded is not None else None,
        "blocks": len(restorer.banded.starts) - 1 if restorer.banded is not None else None,
        "restore_numpy CPU ms/frame, dense (before)": cpu_ms(dense, chunks, args.repeats),
        "restore_numpy CPU ms/frame, now": cpu_ms(restorer.restore_numpy, chunks, args.repeats),
        "max |now - dense| m": float(np.abs(now - before).max()),
        "max |now - float64 exact| m": float(np.abs(now - exact).max()),
        "max |dense - float64 exact| m": float(np.abs(before - exact).max()),
    }
    # the whole pipeline's lengths stage, the dense rounds swapped in, then as committed
    for label, swap in (("dense (before)", True), ("now", False)):
        if swap:
            restorer.restore_numpy = dense
        else:
            del restorer.restore_numpy  # the class's method again
        best = np.inf
        for _ in range(max(1, args.repeats // 2)):
            r = model.animate(motion, stages=Stages(overlap=False))
            best = min(best, r.stage_cpu_seconds["lengths"])
        result[f"pipeline lengths stage CPU ms/frame, {label}"] = 1e3 * best / len(frames)
    print(json.dumps(result, indent=2))
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
