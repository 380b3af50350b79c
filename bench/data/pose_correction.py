"""How far a self-intersecting capture pose would have to turn to clear the body.

In salsa 60_02's lunge anny's left thigh lies up to 3.5 cm inside the belly, and the skirt
caught between the two skins is inside the body whatever the cloth does: that pinch is what
keeps 60_02's mean inside share at 0.103 % (docs/design/PENETRATION.md). Correcting the motion
before simulating it, turning the limb out of the body as a motion-capture clean-up would,
is the fix this script measures. For every frame in which a colliding limb (the legs, for
a skirt) is inside the rest of the body, it searches the smallest turn of the limb that
leaves it outside (depth 0) and ``--clearance`` away from it (room for the fabric), for
three ways of turning it:

- **hip, fastest axis**: the thigh turned at the hip about the axis along which a small
  turn moves the buried skin out fastest (each vertex weighted by how deep it is);
- **hip, towards the reference pose**: the hip's rotation interpolated towards anny's
  A-pose (less flexion, less of everything);
- **knee swing**: the leg turned about the line from the hip to the ankle, which keeps the
  foot where it is (the knee swings out or in).

Each is searched in both directions up to ``--max-degrees``; it reports the angle, how far
the ankle and the knee move, and what a capped turn (``--cap`` degrees) leaves. Geometry
only: the figures are the same on every machine.

``--simulate`` then corrects the first motion as a clean-up step would: the hip turned about
its fastest axis by the smallest angle that leaves the clearance, at most ``--cap`` degrees,
eased in and out over 0.2 s, and simulates it beside the uncorrected motion with the default
cloth (about 4 minutes on 2 cores), judged as bench/data/penetration_regression.py judges, with the
lunging foot's displacement and its lowest point against the floor.

    .venv/bin/python bench/data/pose_correction.py --json runs/pose_correction.json --simulate
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
import torch

from loosefit.motion.pose_correction import LimbTest, fastest_axis, world_rotations

ROOT = Path(__file__).resolve().parents[2]
SALSA = ROOT.parent / "shared" / "mocap" / "cmu-salsa"
# The lunges of configs/regression.yaml: 60_02's, the same mirrored, 60_01's crouch.
MOTIONS = (
    "frames:290:370:{salsa}/60_02.bvh",
    "frames:290:370:mirror:{salsa}/60_02.bvh",
    "frames:150:220:{salsa}/60_01.bvh",
)
LIMB_ROOTS = {
    "left leg": ("LeftUpLeg", "LeftLeg", "LeftFoot"),
    "right leg": ("RightUpLeg", "RightLeg", "RightFoot"),
}


class Turn:
    """One frame's limb turned at its root joint by some degrees, one way of turning."""

    def __init__(self, avatar, motion, t: int, j: int, test: LimbTest, axis) -> None:
        from loosefit.geometry.rotations import rotation_angle

        self.avatar, self.root = avatar, torch.from_numpy(motion.root_translation[t : t + 1])
        self.R, self.j, self.test = motion.rotations[t].astype(np.float64), j, test
        self.axis = None if axis is None else axis / np.linalg.norm(axis)
        self.hip_angle = math.degrees(float(rotation_angle(self.R[j], np.eye(3))))
        self.buried = test.signed(self.pose(0.0, 1.0)[0])[0] < 0  # the skin inside, unturned

    def rotations(self, deg: float, sign: float) -> np.ndarray:
        """(J, 3, 3) the frame's rotations with the turn (no axis: towards the reference)."""
        from loosefit.geometry.rotations import (
            axis_angle_to_matrix,
            matrix_to_quat,
            quat_slerp,
            quat_to_matrix,
        )

        r, j = self.R.copy(), self.j
        if self.axis is None:
            frac = min(deg / max(self.hip_angle, 1e-9), 1.0)
            r[j] = quat_to_matrix(quat_slerp(matrix_to_quat(r[j]), np.array([1.0, 0, 0, 0]), frac))
        else:
            r[j] = axis_angle_to_matrix(sign * math.radians(deg) * self.axis) @ r[j]
        return r

    def pose(self, deg: float, sign: float):
        """(Vb, 3) body and (J, 3) joint positions with the turn."""
        rot = torch.from_numpy(self.rotations(deg, sign)[None].astype(np.float32))
        with torch.no_grad():
            b = self.avatar.pose(rot, self.root)
        return b.vertices[0].double().numpy(), b.joint_poses[0, :, :3, 3].double().numpy()

    def gap(self, deg: float, sign: float) -> float:
        """m the skin that was buried stands outside the rest of the body with the turn
        (negative: inside; and no other vertex of the limb may be inside)."""
        sd = self.test.signed(self.pose(deg, sign)[0])[0]
        worst = float(sd.min())
        return min(float(sd[self.buried].min(initial=np.inf)), worst if worst < 0 else np.inf)

    def smallest(self, target: float, sign: float, max_degrees: float, steps: int) -> float:
        """The smallest turn (degrees, inf up to max_degrees) that leaves ``target`` m: the
        first whole degree that does (a larger turn may bury the limb elsewhere), refined
        by bisection."""
        lo = 0.0
        for hi in np.arange(1.0, max_degrees + 0.5):
            if self.gap(float(hi), sign) >= target:
                for _ in range(steps):
                    mid = 0.5 * (lo + hi)
                    lo, hi = (lo, mid) if self.gap(mid, sign) >= target else (mid, hi)
                return float(hi)
            lo = float(hi)
        return math.inf


def measure(
    avatar, parts, spec: str, clearance: float, max_degrees: float, cap: float, steps: int = 6
) -> dict:
    """Per folded frame and way of turning: the smallest angle that clears, and its cost."""
    from loosefit.motion.motions import load_motion

    motion = load_motion(spec, avatar, fps=30.0)
    names, parents = avatar.joint_names, avatar.skeleton.parents
    rest = avatar.rest_vertices.double().cpu().numpy()
    rows = []
    for limb, (hip, knee, ankle) in LIMB_ROOTS.items():
        if not parts.limb_collides.get(limb, False):
            continue
        test = LimbTest(parts, limb, rest)
        j, jk, ja = names.index(hip), names.index(knee), names.index(ankle)
        for t in range(motion.num_frames):
            still = Turn(avatar, motion, t, j, test, None)
            body, joints = still.pose(0.0, 1.0)
            depth = -test.signed(body)[0].min()
            if depth <= 0:
                continue
            to_parent = world_rotations(still.R, parents)[parents[j]].T
            ways = {
                "hip, fastest axis": to_parent @ fastest_axis(test, body, joints[j], clearance),
                "knee swing": to_parent @ (joints[ja] - joints[j]),
                "hip, towards the reference pose": None,
            }
            for way, axis in ways.items():
                turn = Turn(avatar, motion, t, j, test, axis)
                found = {}
                for sign in (1.0,) if axis is None else (1.0, -1.0):
                    for key, target in (("clear", 0.0), ("clearance", clearance)):
                        angle = turn.smallest(target, sign, max_degrees, steps)
                        if key not in found or angle < found[key][0]:
                            found[key] = (angle, sign)
                at, sign = found["clear"]
                capped = turn.pose(cap, sign)
                moved = (turn.pose(at, sign)[1] if math.isfinite(at) else capped[1]) - joints
                rows.append(
                    {
                        "motion": spec,
                        "limb": limb,
                        "frame": t,
                        "depth_cm": 100 * depth,
                        "way": way,
                        "clear_deg": at,
                        "clearance_deg": found["clearance"][0],
                        "ankle_cm": 100 * float(np.linalg.norm(moved[ja])),
                        "knee_cm": 100 * float(np.linalg.norm(moved[jk])),
                        "capped_depth_cm": 100 * max(-float(test.signed(capped[0])[0].min()), 0.0),
                        "capped_ankle_cm": 100 * float(np.linalg.norm(capped[1][ja] - joints[ja])),
                    }
                )
    return {"frames": motion.num_frames, "rows": rows}


def simulate_pair(
    avatar, parts, spec: str, clearance: float, cap: float, out: Path, workers: int
) -> dict:
    """Simulate ``spec`` as captured and as
    :func:`~loosefit.motion.pose_correction.unfold_motion` corrects it; per clip the figures
    of :func:`~loosefit.eval.dataset_quality.judge_dataset`, the turn, and the feet."""
    from loosefit.data.format import DatasetReader
    from loosefit.eval.dataset_quality import judge_dataset
    from loosefit.motion.motions import load_motion
    from loosefit.motion.pose_correction import UnfoldConfig, unfold_motion
    from loosefit.sim.dataset_config import read_config_file
    from loosefit.sim.generate import generate
    from loosefit.train.frames import avatar_for

    motion = load_motion(spec, avatar, fps=30.0)
    unfolded = unfold_motion(
        avatar, motion, parts, UnfoldConfig(clearance=clearance, max_degrees=cap)
    )
    fixed, degrees = unfolded.motion, unfolded.degrees
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"corrected_{cap:g}deg.npz"
    fixed.save(path)
    config = read_config_file(ROOT / "configs" / "regression.yaml")
    config.preset = "pose-correction"
    config.unfold = UnfoldConfig(enabled=False)  # the two motions as they are
    config.motions.specs = (spec, str(path))
    generate(config, out / "simulated", workers=workers, progress=True)
    reader = DatasetReader(out / "simulated", allow_incomplete=True)
    rows = judge_dataset(reader, avatar_for(reader))
    names = avatar.joint_names
    with torch.no_grad():
        a, b = avatar.pose_motion(motion), avatar.pose_motion(fixed)
    feet = {}
    for side in ("Left", "Right"):
        toe, ankle = names.index(f"{side}ToeBase"), names.index(f"{side}Foot")
        moved = (a.joint_poses[:, ankle, :3, 3] - b.joint_poses[:, ankle, :3, 3]).norm(dim=1)
        feet[side.lower()] = {
            "ankle_moved_cm_max": 100 * float(moved.max()),
            "toe_lowest_cm": [100 * float(x.joint_poses[:, toe, 2, 3].min()) for x in (a, b)],
        }
    return {
        "clips": rows,
        "degrees_max": float(degrees.max()),
        "frames_turned": int((degrees > 0).sum()),
        "feet": feet,
    }


def survey(avatar, parts, folder: Path) -> str:
    """A table: per take, the frames the default correction turns and how far it turns."""
    from loosefit.motion.motions import load_motion
    from loosefit.motion.pose_correction import unfold_motion

    lines = [
        "| take | frames | frames turned (ramps included) | largest turn deg | "
        "fold before, after cm |",
        "|---|---:|---:|---:|---:|",
    ]
    for path in sorted(Path(folder).glob("*.bvh")):
        motion = load_motion(str(path), avatar, fps=30.0, start_frame=10)
        s = unfold_motion(avatar, motion, parts).stats()
        lines.append(
            f"| {path.stem} | {motion.num_frames} | {s['unfold_frames']} | "
            f"{s['unfold_degrees_max']:.1f} | {100 * s['fold_depth_before']:.2f}, "
            f"{100 * s['fold_depth_after']:.2f} |"
        )
    return "\n".join(lines)


def summarize(rows: list[dict]) -> list[dict]:
    """Per motion and way: the worst and median angle to clear, and what the cap leaves."""
    out = []
    keys = sorted({(r["motion"], r["way"]) for r in rows}, key=lambda k: (k[0], k[1]))
    for motion, way in keys:
        rs = [r for r in rows if r["motion"] == motion and r["way"] == way]
        clear = np.array([r["clear_deg"] for r in rs])
        out.append(
            {
                "motion": motion,
                "way": way,
                "folded_frames": len(rs),
                "depth_max_cm": max(r["depth_cm"] for r in rs),
                "clear_deg_median": float(np.median(clear)),
                "clear_deg_max": float(clear.max()),
                "clearance_deg_max": float(max(r["clearance_deg"] for r in rs)),
                "ankle_cm_max": max(r["ankle_cm"] for r in rs if math.isfinite(r["clear_deg"]))
                if np.isfinite(clear).any()
                else math.inf,
                "knee_cm_max": max(r["knee_cm"] for r in rs if math.isfinite(r["clear_deg"]))
                if np.isfinite(clear).any()
                else math.inf,
                "capped_depth_cm_max": max(r["capped_depth_cm"] for r in rs),
                "capped_ankle_cm_max": max(r["capped_ankle_cm"] for r in rs),
            }
        )
    return out


def table(summary: list[dict], cap: float, clearance: float, max_degrees: float) -> str:
    def deg(x: float) -> str:
        return f"> {max_degrees:.0f}" if not math.isfinite(x) else f"{x:.1f}"

    def cm(x: float) -> str:  # (no turn within the search clears it)
        return f"{x:.1f}" if math.isfinite(x) else "-"

    lines = [
        f"| motion | turn | folded frames | deepest cm | to clear, median / worst deg | "
        f"to leave {100 * clearance:.0f} cm, worst deg | ankle moves cm | knee moves cm | "
        f"turned {cap:.0f} deg: deepest cm, ankle cm |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for s in summary:
        name = s["motion"].replace(str(SALSA) + "/", "")
        lines.append(
            f"| {name} | {s['way']} | {s['folded_frames']} | {s['depth_max_cm']:.2f} | "
            f"{deg(s['clear_deg_median'])} / {deg(s['clear_deg_max'])} | "
            f"{deg(s['clearance_deg_max'])} | {cm(s['ankle_cm_max'])} | {cm(s['knee_cm_max'])} | "
            f"{s['capped_depth_cm_max']:.2f}, {s['capped_ankle_cm_max']:.1f} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument(
        "--motions",
        nargs="+",
        default=None,
        help="motion specs (default: the lunges of configs/regression.yaml)",
    )
    ap.add_argument("--clearance", type=float, default=0.01, help="m of room for the fabric")
    ap.add_argument("--max-degrees", type=float, default=45.0, help="the search's limit")
    ap.add_argument("--cap", type=float, default=10.0, help="a 'few degrees' turn to report")
    ap.add_argument("--json", type=Path, default=None, help="write the figures here")
    ap.add_argument(
        "--simulate",
        action="store_true",
        help="also simulate the first motion as captured and corrected",
    )
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "pose_correction")
    ap.add_argument(
        "--survey",
        type=Path,
        default=None,
        metavar="FOLDER",
        help="instead: what the default correction does to every BVH take in "
        "FOLDER (from frame 10, as the salsa preset plays them)",
    )
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args(argv)
    from loosefit.body.avatar import Avatar
    from loosefit.body.regions import body_parts

    if args.motions is None and args.survey is None and not SALSA.is_dir():
        print(f"no salsa clips at {SALSA}: pass --motions", file=sys.stderr)
        return 2
    specs = args.motions or [m.format(salsa=SALSA) for m in MOTIONS]
    avatar = Avatar()
    parts = body_parts(avatar, arms=False)  # the skirt's collider
    if args.survey is not None:
        print(survey(avatar, parts, args.survey))
        return 0
    t0 = time.perf_counter()
    rows = []
    for spec in specs:
        rows += measure(avatar, parts, spec, args.clearance, args.max_degrees, args.cap)["rows"]
    summary = summarize(rows)
    print(table(summary, args.cap, args.clearance, args.max_degrees))
    print(f"\n{time.perf_counter() - t0:.0f} s")
    result = {"summary": summary, "rows": rows}
    if args.simulate:
        torch.set_num_threads(1)
        sim = simulate_pair(
            avatar, parts, specs[0], args.clearance, args.cap, args.out, args.workers
        )
        result["simulated"] = sim
        print(json.dumps(sim, indent=1))
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(result, indent=1, default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
