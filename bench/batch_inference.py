"""Frames per second of the batched motion stage for N characters at once (issue 25, item 4).

N = 1, 16, 256 procedural dances rolled out together (:func:`loosefit.model.rollout.
rollout_batch`), at the CPU resolution (the packaged salsa model, 2,352 vertices) and at the
paper's (the same networks on the 9,352-vertex flared skirt, untrained weights: the cost
does not depend on them). Frames per second counts every character's frames. Writes
``docs/BATCH_INFERENCE.md`` with the machine's name.

    .venv/bin/python bench/batch_inference.py                 # CPU, about 10 min on dev-cpu
    .venv/bin/python bench/batch_inference.py --device cuda   # on a GPU
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import torch

import loosefit
from loosefit.api import motion_for
from loosefit.model.rollout import rollout_batch


def paper_scale(model):
    """The packaged networks' configuration on the paper's 9,352-vertex skirt."""
    from loosefit.dress import fit_skirt
    from loosefit.garment.skirt import SkirtConfig
    from loosefit.model.generative import GarmentGenerativeModel
    from loosefit.model.motion_encoder import DynamicMotionEncoder

    m = model.model
    skirt = fit_skirt(m.avatar(), SkirtConfig.preset("paper", "flared"))
    gen = GarmentGenerativeModel(skirt, m.generative.config)
    enc = DynamicMotionEncoder(gen, m.encoder.num_features, m.encoder.config)
    return gen.eval(), enc.eval(), torch.from_numpy(skirt.vertices).float()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="1,16,256")
    ap.add_argument("--frames", type=int, default=60, help="motion frames per character")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--out", default="docs/BATCH_INFERENCE.md")
    args = ap.parse_args()

    model = loosefit.load(device=args.device)
    m = model.model
    avatar = m.avatar()
    sizes = [int(n) for n in args.sizes.split(",")]
    dances = [
        motion_for("dance:4", avatar, model.fps, args.frames, seed=i) for i in range(max(sizes))
    ]
    scales = {"cpu (2,352 vertices, packaged)": (m.generative, m.encoder, m.rest_state)}
    g, e, rest = paper_scale(model)
    scales["paper (9,352 vertices)"] = (g.to(args.device), e.to(args.device), rest.to(args.device))
    rows = []
    for name, (gen, enc, rest) in scales.items():
        for n in sizes:
            rollout_batch(gen, enc, dances[:1], rest, m.floor_height, m.rollout_config)  # warm
            t0 = time.perf_counter()
            res = rollout_batch(gen, enc, dances[:n], rest, m.floor_height, m.rollout_config)
            if args.device.startswith("cuda"):
                torch.cuda.synchronize()
            seconds = time.perf_counter() - t0
            frames = sum(r.frames for r in res)  # preroll included: it is computed too
            rows.append((name, n, frames / seconds, seconds / res[0].frames))
            print(f"{name}: N={n}: {frames / seconds:.0f} frames/s", flush=True)
    dev = (
        torch.cuda.get_device_name()
        if args.device.startswith("cuda")
        else f"{platform.processor() or platform.machine()}, {torch.get_num_threads()} threads"
    )
    lines = [
        "# Batched inference: N characters at once",
        "",
        f"`bench/batch_inference.py --device {args.device}` on {dev}, torch {torch.__version__}: "
        f"the motion stage (motion encoder + decoders, paper 3.3) of N procedural dances of "
        f"{args.frames} frames rolled out together, one network call per frame for all N "
        "(`Animator.animate_batch`; detail and collision handling then run per character). "
        "Frames per second count every character's frames, the rollout's preroll included.",
        "",
        "| resolution | N | frames per second | seconds per step |",
        "|---|---:|---:|---:|",
        *[f"| {r} | {n} | {fps:,.0f} | {step:.3f} |" for r, n, fps, step in rows],
        "",
    ]
    Path(args.out).write_text("\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
