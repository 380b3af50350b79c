"""How far every known-good motion is from the pose check's thresholds.

The pose check (``loosefit.motion.pose_check``) refuses imported motions a dancer could not
dance. Its thresholds were set from this script's output: each procedural move (three
seeds) and dance, and every clip of ``../shared/mocap/cmu-salsa`` and ``cmu-ballet``
(skipped when absent), retargeted as ``loosefit animate`` loads them, at their own
frame rate (the files 120 fps, the procedural motions 30; the check runs there). Per
motion: the fraction of frames upright (head above hips above the lower foot), the
fraction with the lower sole within 5 cm of the floor, the lowest sole, the fastest
bone (deg/s, which joint, which frame). Two CPU cores, a few minutes::

    .venv/bin/python bench/data/pose_check_margins.py
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from loosefit.body.avatar import Avatar
from loosefit.motion.files import read_clip
from loosefit.motion.motions import PROCEDURAL_NAMES, load_motion
from loosefit.motion.pose_check import (
    CONTACT_M,
    MAX_BELOW_M,
    MAX_TURN_DEG_S,
    MIN_CONTACT,
    MIN_UPRIGHT,
    measure_pose,
)
from loosefit.motion.retarget import RetargetConfig, retarget_bvh

MOCAP = Path(__file__).resolve().parents[3] / "shared" / "mocap"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--mocap",
        type=Path,
        default=MOCAP,
        help="the folder holding cmu-salsa/ and cmu-ballet/ (default: ../shared/mocap)",
    )
    mocap = p.parse_args(argv).mocap
    avatar = Avatar()
    names = avatar.skeleton.names
    specs = [f"{m}" for m in PROCEDURAL_NAMES if m != "dance"]
    specs = [(s, seed) for s in specs for seed in (0, 1, 2)]
    specs += [(f"dance:{d}", seed) for d, seed in ((12, 0), (12, 1), (30, 2))]
    specs += [
        (str(f), 0)
        for folder in ("cmu-salsa", "cmu-ballet")
        for f in sorted((mocap / folder).glob("*.bvh"))
    ]
    config = RetargetConfig(check_pose=False, fps=None)  # files at their own rate
    print(
        f"thresholds: upright >= {MIN_UPRIGHT}, contact (< {CONTACT_M} m) >= {MIN_CONTACT}, "
        f"sole >= -{MAX_BELOW_M} m, turn <= {MAX_TURN_DEG_S} deg/s"
    )
    print(
        f"{'motion':<14} {'frames':>6} {'upright':>7} {'contact':>7} {'sole':>6} "
        f"{'turn':>6}  fastest bone"
    )
    worst = {"upright": 1.0, "contact": 1.0, "sole": 1.0, "turn": 0.0}
    for spec, seed in specs:
        if spec.endswith(".bvh"):
            clip = read_clip(spec, config)
            motion = retarget_bvh(clip, avatar.skeleton, avatar.floor_height, config)
        else:
            motion = load_motion(spec, avatar, fps=30.0, seed=seed)
        m = measure_pose(motion, avatar.skeleton, avatar.floor_height)
        contact = float((m.sole < CONTACT_M).mean())
        near = " ".join(f"{(m.sole < h).mean():.2f}" for h in (0.05, 0.15))
        rise = " ".join(
            f"{((m.torso_rise > k) & (m.legs_rise > k)).mean():.2f}" for k in (0.0, 0.3, 0.7)
        )
        t, j = np.unravel_index(np.argmax(m.turn), m.turn.shape)
        label = Path(spec).stem if spec.endswith(".bvh") else f"{spec}/{seed}"
        print(
            f"{label:<14} {motion.num_frames:>6} {m.upright.mean():>7.3f} {contact:>7.3f} "
            f"{m.sole.min():>6.3f} {m.turn.max():>6.0f}  {names[j]} at frame {t} of "
            f"{motion.fps:.0f} fps; contact at 5, 15 cm: {near}; upright by 0, 0.3, "
            f"0.7: {rise}"
        )
        worst = {
            "upright": min(worst["upright"], float(m.upright.mean())),
            "contact": min(worst["contact"], contact),
            "sole": min(worst["sole"], float(m.sole.min())),
            "turn": max(worst["turn"], float(m.turn.max())),
        }
    print("worst:", {k: round(v, 3) for k, v in worst.items()})
    return 0


if __name__ == "__main__":
    sys.exit(main())
