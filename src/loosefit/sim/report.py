"""A data set's quality report: totals and worst figures over its clips, and the table
printed at the end of a run."""

from __future__ import annotations

import numpy as np


def summarize(manifest: dict) -> dict:
    """Totals and worst quality figures over the clips the dataset keeps.

    Flagged clips count in ``clips`` and in the cost (``seconds_per_frame_mean``,
    over every simulated clip) but not in the frames or the quality figures: those
    describe the data a model trains and is judged on.
    """
    simulated = [e for e in manifest["sequences"].values() if "quality" in e]
    entries = [e for e in simulated if e["status"] == "done"]
    frames = sum(e["frames"] for e in entries)
    spf = [e["seconds_per_frame"] for e in simulated]
    timed = [e["seconds"] for e in simulated if "seconds" in e]

    def worst(key: str) -> float:
        return max((e["quality"].get(key, 0.0) for e in entries), default=0.0)

    return {
        "clips": len(manifest["sequences"]),
        "clips_ok": sum(e["status"] == "done" for e in manifest["sequences"].values()),
        "frames": frames,
        "seconds_per_frame_mean": float(np.mean(spf)) if spf else None,
        # clips of this data set's length simulated per hour (a batch's time shared out)
        "clips_per_hour": 3600.0 * len(timed) / sum(timed) if sum(timed) > 0 else None,
        "inside_max": worst("inside_max"),
        "penetration_max": worst("penetration_max"),
        "inside_depth_max": worst("inside_depth_max"),
        "inside_mean": float(np.mean([e["quality"].get("inside_mean", 0) for e in entries]))
        if entries
        else None,
        "strain_p99_max": worst("strain_p99"),
        "max_speed": worst("max_speed"),
        "nan_count": int(sum(e["quality"].get("nan_count", 0) for e in entries)),
    }


def _devices(manifest: dict) -> list[str]:
    """The devices the clips were simulated on (an entry without one: the manifest's)."""
    default = manifest.get("config", {}).get("cloth", {}).get("device", "cpu")
    return sorted({e.get("device", default) for e in manifest["sequences"].values()} or {default})


def format_report(manifest: dict) -> str:
    """A plain-text table of each clip's quality, for the end of a run.

    Columns: the share of garment vertices inside the body (mean over frames, and the
    worst frame), the worst frame's share deeper than 5 mm, the deepest vertex, the edge
    strain p99, the fastest vertex, the frames whose capture pose was turned out of the body
    (:mod:`loosefit.motion.pose_correction`, with the largest turn), and the frames in which
    the pose still folds into itself (a limb inside the rest of the body, with how deep), where
    cloth is pinched.
    """
    width = max([14, *(len(n) + 2 for n in manifest["sequences"])])
    lines = [
        f"{'clip':<{width}}{'split':<7}{'frames':>7}{'s/frame':>9}{'inside mean':>13}"
        f"{'inside max':>12}{'> 5 mm':>8}{'depth cm':>10}{'strain p99':>12}{'speed':>8}"
        f"{'turned':>14}{'folds':>12}  status"
    ]
    folding = []
    for name, e in manifest["sequences"].items():
        q = e.get("quality", {})
        n_fold = e.get("overlap_frames")
        if n_fold:
            folding.append(name)
            folds = f"{n_fold}, {100 * e.get('overlap_depth_max', 0.0):.1f} cm"
        else:
            folds = "-" if n_fold is None else "0"
        n_turn = e.get("unfold_frames")
        turned = "-" if n_turn is None else "0"
        if n_turn:
            turned = f"{n_turn}, {e.get('unfold_degrees_max', 0.0):.1f} deg"
        lines.append(
            f"{name:<{width}}{'test' if e.get('test') else 'train':<7}{e.get('frames', 0):>7}"
            f"{e.get('seconds_per_frame', float('nan')):>9.2f}"
            f"{q.get('inside_mean', float('nan')):>13.5f}"
            f"{q.get('inside_max', float('nan')):>12.4f}"
            f"{q.get('penetration_max', float('nan')):>8.4f}"
            f"{100 * q.get('inside_depth_max', float('nan')):>10.2f}"
            f"{q.get('strain_p99', float('nan')):>12.3f}"
            f"{q.get('max_speed', float('nan')):>8.2f}{turned:>14}{folds:>12}  {e['status']}"
            + (f" ({e['reason']})" if e.get("reason") else "")
        )
    s = manifest.get("summary", {})
    lines.append(
        f"{s.get('clips_ok', 0)}/{s.get('clips', 0)} clips kept, {s.get('frames', 0)} frames; "
        f"split {len(manifest['split']['train'])} train / {len(manifest['split']['test'])} test"
    )
    if s.get("clips_per_hour"):
        lines.append(
            f"{s['seconds_per_frame_mean']:.3f} s per frame per clip, "
            f"{s['clips_per_hour']:.1f} clips per hour "
            f"(device {', '.join(_devices(manifest))})"
        )
    if folding:
        lines.append(
            f"the body folds into itself (a limb inside the rest of it) in {len(folding)} "
            f"clip(s): cloth caught there is pinched; where and how deep: loosefit diagnose "
            f"DATASET {folding[0]} (docs/design/PENETRATION.md)"
        )
    return "\n".join(lines)
