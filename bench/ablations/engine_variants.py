"""Engine tiers trained other ways, side by side: RMSE, hem flare at the fastest turn and the
median edge change against the simulation, with and without the capsule push-out, on
held-out clips (no inside-body test: seconds, not the minutes of ``engine_tier.py``).

    python bench/ablations/engine_variants.py runs/engine/engine.pt \\
        runs/engine-membrane/engine.pt --data datasets/dance
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

from loosefit.body.capsules import avatar_capsules
from loosefit.data.format import DatasetReader
from loosefit.eval.heading import fastest_turn
from loosefit.eval.hem import hem_flare
from loosefit.eval.metrics import rmse
from loosefit.eval.stage_account import TURN_WINDOW
from loosefit.garment.mesh_checks import hem_loop
from loosefit.inference.engine.export import EngineStep, skeleton_record
from loosefit.inference.engine.model import load_engine, rollout_engine
from loosefit.model.losses import ClothStructure, signed_edge_change


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("engines", nargs="+", help="engine.pt files")
    p.add_argument("--data", default="datasets/dance")
    p.add_argument("--clips", default="chain_60_03_60_07_61_03_61_07,05_10")
    args = p.parse_args()
    torch.set_num_threads(1)
    reader = DatasetReader(args.data)
    print("| engine | clip | push-out | RMSE cm | flare error at turn | edge change p50 |")
    print("|---|---|---|---:|---:|---:|")
    for path in args.engines:
        model = load_engine(path)
        avatar = model.avatar()
        step = EngineStep(model, avatar_capsules(avatar), skeleton_record(avatar)).eval()
        hem = hem_loop(model.template.vertices, model.template.faces)
        structure = ClothStructure.from_template(model.template)
        for name in args.clips.split(","):
            seq = reader.read(name)
            truth = np.asarray(seq.garment_vertices, np.float32)
            pelvis = avatar.pose_motion(seq.motion).joint_poses[:, 0, :3, 3].numpy()
            turn = fastest_turn(seq.motion.rotations[:, 0], seq.motion.fps, 5, "gradient")
            w = slice(max(turn - TURN_WINDOW, 0), turn + TURN_WINDOW + 1)
            truth_flare = hem_flare(truth, pelvis, hem)[w]
            for label, collide in (("no", None), ("yes", step)):
                x = rollout_engine(model, seq.motion, collide=collide)
                error = np.mean(np.abs(hem_flare(x, pelvis, hem)[w] / truth_flare - 1))
                change = signed_edge_change(
                    torch.from_numpy(x), structure.edges, structure.rest_lengths
                ).numpy()
                print(
                    f"| {path} | {name} | {label} | {100 * rmse(x, truth):.2f} | "
                    f"{error:.1%} | {np.median(change):+.2%} |",
                    flush=True,
                )


if __name__ == "__main__":
    main()
