"""Figures behind docs/design/MOTION.md's reading of Table 1 and its limits, for a motion
checkpoint.

On the held-out clips: the RMSE over successive 100-frame blocks of the rollout, of the
reference (the rest drape carried by the root: how hard each stretch of motion is) and of
the oracle (the generative model's own code of the simulation, decoded: the floor), and the
edge strain and the share of vertices inside the body of the rollout against the
simulation's. On the procedural spin (first 40
frames, as in tests/test_checkpoints.py): the largest share of vertices inside the body::

    python bench/quality/motion_quality.py --checkpoint checkpoints/salsa/motion.pt \\
        --data datasets/salsa
"""

from __future__ import annotations

import argparse

import numpy as np

from loosefit.body.avatar import Avatar, AvatarConfig
from loosefit.data.format import DatasetReader
from loosefit.eval.metrics import inside_fraction, rmse_per_frame
from loosefit.garment.quality import edge_strain
from loosefit.inference.animator import load_animation_model
from loosefit.motion.motions import load_motion


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--checkpoint", default="checkpoints/salsa/motion.pt")
    p.add_argument("--data", default="datasets/salsa")
    p.add_argument("--block", type=int, default=100, help="frames per block")
    args = p.parse_args()
    model = load_animation_model(args.checkpoint)
    reader = DatasetReader(args.data)
    avatar = Avatar(AvatarConfig(shape=dict(model.body.get("shape", {}))))
    collider = avatar.collider_faces(arms=False)
    for name in reader.split("test"):
        seq = reader.read(name)
        truth = seq.garment_vertices
        pred = model.animate(seq.motion).vertices
        print(f"{name}: RMSE (cm) per {args.block}-frame block, rollout / reference / oracle")
        for label, v in (
            ("rollout", pred),
            ("reference", model.carry_drape(seq.motion).vertices),
            ("oracle", model.reconstruct(seq.motion, truth).vertices),
        ):
            per = 100 * rmse_per_frame(v, truth)
            blocks = [
                np.sqrt(np.mean(per[i : i + args.block] ** 2))
                for i in range(0, len(per), args.block)
            ]
            print(f"  {label:9s} " + " ".join(f"{b:.1f}" for b in blocks))
        for label, v in (("simulation", truth), ("rollout", pred)):
            strain, _ = edge_strain(v, model.template)
            q = np.percentile(strain, [50, 99])
            print(f"  edge strain, {label}: median {q[0]:.3f}, p99 {q[1]:.3f}")
        body = avatar.pose_motion(seq.motion).vertices
        for label, v in (("simulation", truth), ("rollout", pred)):
            inside = 100 * inside_fraction(v, body, collider)
            print(
                f"  vertices inside the body, {label}: mean {inside.mean():.2f} %, "
                f"p99 {np.percentile(inside, 99):.1f} %, max {inside.max():.1f} % "
                f"per frame"
            )
    motion = load_motion("spin", avatar, fps=model.fps).slice(0, 40)
    body = avatar.pose_motion(motion)
    inside = inside_fraction(model.animate(motion).vertices, body.vertices, collider)
    print(
        f"procedural spin, 40 frames: at most {100 * inside.max():.1f} % of the vertices "
        "inside the body"
    )


if __name__ == "__main__":
    main()
