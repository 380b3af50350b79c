"""docs/results/TURN_FLARE.md: the hem at each clip's fastest turn, and what makes a turn miss.

Part 1, for each motion stage given (``--sets NAME=MOTION.pt``): on every clip of a data set
(training, validation and held-out, each marked), over the 61 frames around the clip's
fastest turn (:func:`loosefit.eval.motion_signals.fastest_turn`), the motion stage's hem
flare (the hem ring's mean distance from the pelvis's vertical axis) and the hem's speed,
each over the simulation's. Training clips show what the stage can fit, the others what it
carries to motion it has not seen.

Part 2, for one clip (``--probe``): the first set's flare at that turn when the motion stage
is given the clip changed one way at a time: the simulation's garment as its previous
state every N frames (``restart_every``: drift or the stage's own map?), the joints below
the root at rest (which body parts it reads), the turn scaled (the heading's yaw), the
pelvis's tilt taken out (the root's rotation its heading alone); and each clip's pelvis
pitch, the capture's tilt the features carry::

    OMP_NUM_THREADS=1 python bench/quality/turn_flare.py --data datasets/dance \\
        --sets shipped=checkpoints/dance/motion.pt --probe 05_02 \\
        --out docs/results/TURN_FLARE.md

The motion stage alone (no collision handling), deterministic, one thread.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

import loosefit
from loosefit.data.format import DatasetReader
from loosefit.eval.ensemble import turn_window
from loosefit.eval.heldout import validation_clips
from loosefit.eval.hem import hem_flare, hem_speed
from loosefit.eval.motion_signals import fastest_turn, turn_extent, turn_rate
from loosefit.garment.mesh_checks import hem_loop
from loosefit.inference.stages import MOTION_ONLY
from loosefit.model.motion_features import heading_yaw, yaw_matrix
from loosefit.motion.pelvis import pelvis_pitch
from loosefit.train.common import machine

UPPER = ("Spine1", "Spine2", "Neck", "Head", "Shoulder", "Arm", "Hand", "Thumb", "Finger")
LEGS = ("UpLeg", "Leg", "Foot", "Toe")


def turn_means(garment, motion, hem) -> tuple[float, float]:
    """(flare m, speed m/s): the hem's mean flare and mean vertex speed over the 61 frames
    around the motion's fastest turn. garment: (T, V, 3) world, T <= the motion's frames;
    hem: (H,)."""
    T = len(garment)
    w = turn_window(fastest_turn(motion), T)
    flare = hem_flare(garment, np.asarray(motion.root_translation)[:T], hem)[w].mean()
    speed = hem_speed(garment, hem, motion.fps)[w].mean()
    return float(flare), float(speed)


def turn_ratios(garment, truth, motion, hem) -> tuple[float, float]:
    """(flare, speed): the garment's :func:`turn_means` over the truth's, on the frames both
    have. garment, truth: (T, V, 3) world; hem: (H,)."""
    T = min(len(garment), len(truth))
    (gf, gs), (tf, ts) = (turn_means(x[:T], motion, hem) for x in (garment, truth))
    return gf / tf, gs / ts


def with_rotations(motion, rotations: np.ndarray):
    """The motion with other joint rotations (T, J, 3, 3)."""
    return replace(motion, rotations=np.asarray(rotations, motion.rotations.dtype))


def root_parts(rotations: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
    """(T,) the root's unwrapped heading yaw and (T, 3, 3) its tilt (the rotation left
    after the heading), from (T, J, 3, 3) rotations."""
    R = torch.as_tensor(rotations[:, 0], dtype=torch.float64)
    yaw = heading_yaw(R)
    tilt = yaw_matrix(yaw).transpose(-1, -2) @ R
    return torch.as_tensor(np.unwrap(yaw.numpy())), tilt


def probe_variants(motion, truth) -> list[tuple[str, object, dict]]:
    """(label, motion, animate keywords) of each change to the clip, one at a time."""
    R = np.asarray(motion.rotations)
    names = list(motion.joint_names)
    out = [("the clip, free rollout", motion, {})]
    for every in (1, 5, 15, 30):
        what = "every frame" if every == 1 else f"every {every} frames"
        out.append(
            (
                f"the previous garment reset to the simulation's {what}",
                motion,
                {"truth": truth, "restart_every": every},
            )
        )
    for label, parts in (
        ("every joint below the root at rest", None),
        ("the arms, shoulders, upper spine, neck and head at rest", UPPER),
        ("the legs at rest", LEGS),
    ):
        Rn = R.copy()
        which = [
            i
            for i, n in enumerate(names)
            if i > 0 and (parts is None or any(p in n for p in parts))
        ]
        Rn[:, which] = np.eye(3)
        out.append((label, with_rotations(motion, Rn), {}))
    yaw, tilt = root_parts(R)
    for scale in (1.3, 0.7):
        Rn = R.copy()
        Rn[:, 0] = (yaw_matrix(scale * yaw) @ tilt).numpy()
        out.append(
            (
                f"the turn {scale:g}x (the heading's yaw scaled, tilt kept)",
                with_rotations(motion, Rn),
                {},
            )
        )
    Rn = R.copy()
    Rn[:, 0] = yaw_matrix(yaw).numpy()
    out.append(
        (
            "the pelvis's tilt taken out (the root's rotation its heading alone)",
            with_rotations(motion, Rn),
            {},
        )
    )
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--data", default="datasets/dance")
    p.add_argument(
        "--sets", nargs="+", default=["shipped=checkpoints/dance/motion.pt"], help="NAME=MOTION.pt"
    )
    p.add_argument("--clips", nargs="*", help="only these clips in part 1 (default: every one)")
    p.add_argument("--probe", default="05_02", help="the clip of part 2 (none: no part 2)")
    p.add_argument("--out", default="docs/results/TURN_FLARE.md")
    p.add_argument("--about", default="", help="a paragraph on how the sets were made")
    p.add_argument("--threads", type=int, default=1)
    args = p.parse_args()
    torch.set_num_threads(args.threads)
    t0, started = time.perf_counter(), time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    reader = DatasetReader(args.data)
    kinds = {c: "training" for c in reader.split("train")}
    kinds.update({c: "held out" for c in reader.split("test")})
    kinds.update({c: "validation" for c in validation_clips(reader)})
    if args.clips:
        unknown = sorted(set(args.clips) - set(kinds))
        if unknown:
            p.error(f"--clips: {unknown} are not clips of {args.data} ({sorted(kinds)})")
        kinds = {c: k for c, k in kinds.items() if c in args.clips}
    sets = dict(s.split("=", 1) for s in args.sets)
    models = {name: loosefit.load(path).model for name, path in sets.items()}
    rows = []
    for clip, kind in kinds.items():
        seq = reader.read(clip)
        motion, truth = seq.motion, np.asarray(seq.garment_vertices, np.float32)
        hem = hem_loop(seq.template.vertices, seq.template.faces)
        rates = turn_rate(motion)
        fastest = fastest_turn(motion)
        seconds, turns = turn_extent(rates, fastest, motion.fps)
        pitch = float(np.median(pelvis_pitch(motion.rotations)))
        flare = 100.0 * turn_means(truth, motion, hem)[0]
        row = [clip, kind, abs(float(rates[fastest])), seconds, turns, pitch, flare]
        for model in models.values():
            g = np.asarray(model.animate(motion, stages=MOTION_ONLY).vertices)
            row.append(turn_ratios(g, truth, motion, hem))
        rows.append(row)
        print(f"{clip}: done", flush=True)
    lines = [
        "# The hem at the fastest turn",
        "",
        "Made by `python bench/quality/turn_flare.py` (its docstring gives the command) on "
        f"`{args.data}` with "
        + ", ".join(f"{n} = `{p}`" for n, p in sets.items())
        + f"; run {started} on {machine('cpu')}, {time.perf_counter() - t0:.0f} s for part 1.",
        "",
        *([args.about, ""] if args.about else []),
        "## The motion stage's hem over the simulation's, around each clip's fastest turn",
        "",
        "Over the 61 frames around the fastest turn: the hem's flare (mean distance from the "
        "pelvis's vertical axis) and its mean vertex speed, the motion stage alone over the "
        "simulation; the turn's rate (rad/s), how long it stays above half that rate and how "
        "far it turns in that time (a brief flick and a built-up pirouette tell apart here); "
        "the pelvis's median pitch over the clip "
        "(degrees; the forward axis above the horizontal: the capture's tilt the motion "
        "features carry); the simulation's flare there (cm).",
        "",
        "| clip | split | turn rad/s | turn s | turns | pelvis pitch deg | simulated flare cm | "
        + " | ".join(f"{n}: flare | {n}: speed" for n in sets)
        + " |",
        "|---|---|---:|---:|---:|---:|---:|" + "---:|---:|" * len(sets),
    ]
    for clip, kind, rate, seconds, turns, pitch, flare, *ratios in rows:
        cells = " | ".join(f"{f:.3f} | {s:.3f}" for f, s in ratios)
        lines.append(
            f"| {clip} | {kind} | {rate:.1f} | {seconds:.2f} | {turns:.2f} | {pitch:+.1f} | "
            f"{flare:.1f} | {cells} |"
        )
    lines.append("")
    for k, name in enumerate(sets):
        for kind in ("training", "validation", "held out"):
            r = [row[7 + k] for row in rows if row[1] == kind]
            if r:
                f, s = np.array(r).T
                lines.append(
                    f"- {name}, {kind} clips: flare {f.min():.2f}-{f.max():.2f}x, speed "
                    f"{s.min():.2f}-{s.max():.2f}x the simulation's."
                )
    if args.probe != "none":
        seq = reader.read(args.probe)
        motion, truth = seq.motion, np.asarray(seq.garment_vertices, np.float32)
        hem = hem_loop(seq.template.vertices, seq.template.faces)
        model = next(iter(models.values()))
        pitch = pelvis_pitch(motion.rotations)
        w = turn_window(fastest_turn(motion), len(truth))
        lines += [
            "",
            f"## What makes `{args.probe}`'s turn miss ({next(iter(sets))})",
            "",
            f"The motion stage given `{args.probe}` changed one way at a time; its hem flare and "
            f"speed over the 61 frames of the turn over the simulation's. The pelvis's pitch: "
            f"{np.median(pitch):+.1f} degrees over the clip (median), {pitch[w].mean():+.1f} "
            "over the turn.",
            "",
            "| the motion stage given | flare | speed |",
            "|---|---:|---:|",
        ]
        for label, m, kw in probe_variants(motion, truth):
            g = np.asarray(model.animate(m, stages=MOTION_ONLY, **kw).vertices)
            f, s = turn_ratios(g, truth, motion, hem)
            lines.append(f"| {label} | {f:.3f} | {s:.3f} |")
            print(f"probe: {label}: {f:.3f}", flush=True)
    Path(args.out).write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out} in {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
