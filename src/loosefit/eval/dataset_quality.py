"""A simulated data set judged clip by clip for cloth inside the body.

:func:`judge_dataset`: per clip, the share of garment vertices inside the body, how much of
it falls in frames whose pose folds into itself, the deepest vertex, strain, and whether the
data set's quality limits keep the clip.
"""

from __future__ import annotations

import numpy as np
import torch

from loosefit.data.format import DatasetReader
from loosefit.garment.quality import quality
from loosefit.sim.dataset_config import QualityLimits
from loosefit.sim.manifest import LEGACY_CLOTH


def judge_dataset(reader: DatasetReader, avatar) -> dict:
    """Per clip figures of a simulated data set, from its sequences and posed bodies.

    Besides the quality figures (:func:`~loosefit.garment.quality.quality`), the share of
    the inside mean that falls in frames whose pose folds into itself (a limb inside the
    rest of the body, the frames the collider is flattened in:
    :func:`~loosefit.sim.overlap.flatten_overlaps`), and the inside mean measured against
    that flattened collider, the body the cloth actually met.

    Args:
        reader: the data set (finished or not; a clip not simulated yet is left out).
        avatar: the avatar it was simulated on (its manifest's body shape).

    Returns:
        clip -> its figures (``status`` and ``reason`` only for a clip without quality).
    """
    from loosefit.body.regions import body_parts
    from loosefit.geometry.query import closest_points
    from loosefit.sim.overlap import flatten_overlaps

    # a data set made before a cloth field existed was made with LEGACY_CLOTH's value
    cloth = {**LEGACY_CLOTH, **reader.manifest["config"]["cloth"]}
    arms = cloth.get("arm_collision", False)
    faces = avatar.collider_faces(arms=arms).cpu().numpy()
    parts = body_parts(avatar, arms=arms)
    limits = QualityLimits(**reader.manifest["config"].get("limits", {}))
    rows = {}
    for name, entry in reader.manifest["sequences"].items():
        if "quality" not in entry:
            rows[name] = {"status": entry.get("status"), "reason": entry.get("reason", "")}
            continue
        seq = reader.read(name)
        with torch.no_grad():
            body = avatar.pose_motion(seq.motion).vertices.cpu().numpy()
        q = quality(seq.garment_vertices, reader.template, body, faces, seq.motion.fps)
        inside = np.asarray(q["inside_fraction"])  # (T,)
        flat = flatten_overlaps(body, parts, cloth["overlap_inset"])
        folded = flat.moved > 0  # (T,) frames whose pose folds into itself
        inside_flat = inside.copy()
        for t in np.nonzero(folded)[0]:
            inside_flat[t] = closest_points(
                flat.vertices[t], faces, seq.garment_vertices[t]
            ).inside.mean()
        rows[name] = {
            "frames": int(seq.motion.num_frames),
            "inside_mean_pct": 100 * q["inside_mean"],
            "inside_p99_pct": 100 * float(np.percentile(inside, 99)),
            # the part of inside_mean_pct in self-intersecting frames; against the collider
            "inside_folded_pct": 100 * float(inside[folded].sum() / len(inside)),
            "inside_collider_pct": 100 * float(inside_flat.mean()),
            "deep_max_pct": 100 * q["penetration_max"],
            "depth_max_cm": 100 * q["inside_depth_max"],
            "strain_p99": q["strain_p99"],
            "seconds_per_frame": entry.get("seconds_per_frame"),
            "overlap_frames": entry.get("overlap_frames"),
            "overlap_depth_cm": 100 * entry.get("overlap_depth_max", 0.0),
            "kept": bool(
                q["inside_depth_max"] <= limits.max_inside_depth
                and q["penetration_max"] <= limits.max_penetration_fraction
            ),
        }
    return rows
