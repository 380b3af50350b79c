"""A simulated data set judged clip by clip (loosefit.eval.dataset_quality), on the toy data
set: its figures against the quality figures of each clip computed here."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
import torch

from loosefit.data.format import DatasetReader
from loosefit.eval.dataset_quality import judge_dataset
from loosefit.garment.quality import quality
from loosefit.sim.dataset_config import QualityLimits


@pytest.fixture(scope="module")
def judged(toy_dataset, avatar, tmp_path_factory):
    root = tmp_path_factory.mktemp("judged") / "ds"
    shutil.copytree(toy_dataset, root)
    manifest = json.loads((root / "manifest.json").read_text())
    manifest["sequences"] = {
        "a": {"quality": {}, "seconds_per_frame": 1.5, "overlap_frames": 0},
        "c": {"quality": {}, "seconds_per_frame": 2.0, "overlap_depth_max": 0.004},
        "gone": {"status": "failed", "reason": "the cloth tore"},
    }
    (root / "manifest.json").write_text(json.dumps(manifest))
    reader = DatasetReader(root, allow_incomplete=True)
    return reader, judge_dataset(reader, avatar)


def test_a_clip_without_quality_keeps_its_status(judged):
    _, rows = judged
    assert rows["gone"] == {"status": "failed", "reason": "the cloth tore"}
    assert set(rows) == {"a", "c", "gone"}


def test_each_clip_s_figures_are_its_quality(judged, avatar):
    reader, rows = judged
    faces = avatar.collider_faces(arms=False).cpu().numpy()
    limits = QualityLimits()
    for name, entry in (("a", {"seconds_per_frame": 1.5}), ("c", {"seconds_per_frame": 2.0})):
        seq = reader.read(name)
        with torch.no_grad():
            body = avatar.pose_motion(seq.motion).vertices.cpu().numpy()
        q = quality(seq.garment_vertices, reader.template, body, faces, seq.motion.fps)
        row = rows[name]
        assert row["frames"] == seq.motion.num_frames
        assert row["inside_mean_pct"] == 100 * q["inside_mean"]
        inside = np.asarray(q["inside_fraction"])
        assert row["inside_p99_pct"] == 100 * float(np.percentile(inside, 99))
        assert row["deep_max_pct"] == 100 * q["penetration_max"]
        assert row["depth_max_cm"] == 100 * q["inside_depth_max"]
        assert row["strain_p99"] == q["strain_p99"]
        assert row["seconds_per_frame"] == entry["seconds_per_frame"]
        assert 0 <= row["inside_folded_pct"] <= row["inside_mean_pct"] + 1e-12
        if row["inside_folded_pct"] == 0:  # no frame folds: the collider is the body as posed
            assert row["inside_collider_pct"] == pytest.approx(row["inside_mean_pct"])
        kept = (
            q["inside_depth_max"] <= limits.max_inside_depth
            and q["penetration_max"] <= limits.max_penetration_fraction
        )
        assert row["kept"] == kept
    assert rows["c"]["overlap_depth_cm"] == pytest.approx(0.4)
    assert rows["a"]["overlap_depth_cm"] == 0.0 and rows["a"]["overlap_frames"] == 0
