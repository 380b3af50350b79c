"""What collision handling leaves inside the body on hard poses.

The pipeline (default: the committed set) animates the penetration regression set's
motions (``configs/regression.yaml``: the crouches of salsa 60_02, mirrored and 1.5x, 60_01's
crouch, a 1.5x spin), salsa 60_01's opening (a hand on the hip), the account's three ballet
clips and the spin. Per clip: the frames with a vertex inside the whole body (arms and
hands included) by the generalised winding number, those deeper than 5 mm, the deepest,
the mean share of vertices inside; what the collision handler itself reported; the same
depth against the trunk alone (torso, head, legs: where a hand sinks into the hip, the
whole body's closest skin to the cloth under it can be the hand's, inside the hip); the
longest edge against its rest length and the frames with an edge over twice it (a push
that tears the cloth). No simulation is needed: the body is the reference.

    .venv/bin/python bench/quality/hard_poses.py [--checkpoint checkpoints/salsa/motion.pt] \\
        [--out docs/results/HARD_POSES.md] [--set stretch=3.0 ...]
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import platform
import time
from pathlib import Path

import numpy as np
import torch

import loosefit
from loosefit.eval.depth import inside_depths
from loosefit.garment.quality import PENETRATION_TOLERANCE
from loosefit.geometry.edges import unique_edges
from loosefit.sim.dataset_config import read_config_file, resolve_spec
from loosefit.sim.jobs import spec_name
from loosefit.train.common import machine

# the figures of a page docs/X.md as JSON: bench/figures/X.json
FIGURES = Path(__file__).resolve().parents[1] / "figures"


ROOT = Path(__file__).resolve().parents[2]
EXTRA = [  # beyond the regression set: (spec, first frame, frames)
    ("../shared/mocap/cmu-salsa/60_01.bvh", 10, 90),
    ("../shared/mocap/cmu-ballet/05_02.bvh", 0, None),
    ("../shared/mocap/cmu-ballet/05_10.bvh", 0, None),
    ("../shared/mocap/cmu-ballet/05_12.bvh", 0, None),
    ("spin", 0, None),
]


def motions(config: Path) -> list[tuple[str, str, int, int | None]]:
    """(name, spec, first frame, frames) of every clip measured."""
    cfg = read_config_file(config)
    out = [(spec_name(s), s, 0, None) for s in cfg.motions.specs]
    for spec, start, frames in EXTRA:
        resolved = resolve_spec(spec, ROOT)
        name = Path(spec).stem + (f"_{start}-{start + frames}" if frames else "")
        out.append((name, resolved, start, frames))
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--checkpoint", default="checkpoints/salsa/motion.pt")
    p.add_argument("--config", default="configs/regression.yaml")
    p.add_argument("--out", default="docs/results/HARD_POSES.md")
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="FIELD=VALUE",
        help="a CollisionConfig field for this run (a comparison of settings)",
    )
    args = p.parse_args()

    from loosefit.api import motion_for

    torch.set_num_threads(1)
    model = loosefit.load(args.checkpoint).model
    settings = {}
    for item in args.set:
        field, _, value = item.partition("=")
        kind = type(getattr(model.collision, field))
        settings[field] = value.lower() == "true" if kind is bool else kind(value)
    stack = contextlib.ExitStack()  # the settings for the whole run
    stack.enter_context(model.configured(dataclasses.replace(model.collision, **settings)))
    avatar = model.avatar()
    t = model.template
    edges = unique_edges(np.asarray(t.faces))[0]
    rest = np.linalg.norm(t.vertices[edges[:, 0]] - t.vertices[edges[:, 1]], axis=1)
    whole = avatar.collider_faces(arms=True).cpu().numpy()
    trunk = avatar.collider_faces(arms=False).cpu().numpy()  # torso, head and legs
    rows, record = [], {}
    for name, spec, start, frames in motions(Path(args.config)):
        if "shared/mocap" in spec and not (ROOT / "../shared/mocap").exists():
            raise SystemExit(f"{spec}: ../shared/mocap is not beside the project")
        motion = motion_for(spec, avatar, model.fps, frames, start)
        t0 = time.perf_counter()
        result = model.animate(motion)
        seconds = time.perf_counter() - t0
        body = avatar.pose_motion(motion).vertices.cpu().numpy()
        share, deep = inside_depths(result.vertices, body, whole)
        # where a hand sinks into the hip, the whole body's closest skin to cloth under it
        # can be the hand's, inside the hip: the depth into the trunk alone, too
        _, trunk_deep = inside_depths(result.vertices, body, trunk)
        x = np.asarray(result.vertices)
        worst = (np.linalg.norm(x[:, edges[:, 0]] - x[:, edges[:, 1]], axis=-1) / rest).max(1)
        reported = np.array([c["depth_after"] for c in result.collisions])
        r = {
            "frames": motion.num_frames,
            "frames_inside": int((deep > 0).sum()),
            "frames_deep": int((deep > PENETRATION_TOLERANCE).sum()),
            "deepest_cm": 100 * float(deep.max()),
            "inside_mean": float(share.mean()),
            "reported_deepest_cm": 100 * float(reported.max()) if len(reported) else 0.0,
            "trunk_frames_deep": int((trunk_deep > PENETRATION_TOLERANCE).sum()),
            "trunk_deepest_cm": 100 * float(trunk_deep.max()),
            "worst_edge": float(worst.max()),
            "frames_edge_over_2x": int((worst > 2).sum()),
            "ms_per_frame": 1000 * seconds / motion.num_frames,
        }
        record[name] = r
        print(name, r, flush=True)
        rows.append(
            f"| {name} | {r['frames']} | {r['frames_inside']} | {r['frames_deep']} | "
            f"{r['deepest_cm']:.2f} | {100 * r['inside_mean']:.4f} | "
            f"{r['reported_deepest_cm']:.2f} | {r['trunk_frames_deep']} | "
            f"{r['trunk_deepest_cm']:.2f} | {r['worst_edge']:.2f} | "
            f"{r['frames_edge_over_2x']} | {r['ms_per_frame']:.0f} |"
        )
    head = (
        "| clip | frames | frames with cloth inside | frames > 5 mm | deepest (cm) | "
        "inside, mean % of vertices | handler's own deepest (cm) | "
        "frames > 5 mm into the trunk | deepest into the trunk (cm) | longest edge / rest | "
        "frames with an edge > 2x rest | ms / frame |\n"
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    )
    out = Path(args.out)
    (FIGURES / f"{out.stem}.json").write_text(
        json.dumps(
            {
                "checkpoint": args.checkpoint,
                "collision": dataclasses.asdict(model.collision),
                "machine": machine("cpu"),
                "platform": platform.platform(),
                "clips": record,
            },
            indent=1,
        )
    )
    marker = "<!-- hard poses table -->"
    body = head + "\n" + "\n".join(rows)
    if out.is_file() and marker in out.read_text():
        out.write_text(out.read_text().split(marker)[0] + marker + "\n" + body + "\n")
    else:
        out.write_text(f"# Hard poses\n\n{marker}\n{body}\n")
    print(body)


if __name__ == "__main__":
    main()
