"""A data set's quality summary (loosefit.sim.report)."""

from __future__ import annotations

from loosefit.sim.report import summarize


def test_summary_quality_covers_the_kept_clips_only():
    def entry(status, frames, inside, spf):
        q = {"inside_max": inside, "strain_p99": 0.05, "max_speed": 3.0, "nan_count": 0}
        return {"status": status, "frames": frames, "seconds_per_frame": spf, "quality": q}

    crashed = {"status": "flagged", "frames": 10, "reason": "NaN"}
    manifest = {
        "sequences": {
            "a": entry("done", 100, 0.01, 2.0),
            "b": entry("flagged", 50, 0.40, 4.0),
            "c": crashed,
        }
    }
    s = summarize(manifest)
    assert s["clips"] == 3 and s["clips_ok"] == 1 and s["frames"] == 100
    assert s["inside_max"] == 0.01  # not the flagged clip's 0.40
    assert s["seconds_per_frame_mean"] == 3.0  # the cost counts every simulated clip
