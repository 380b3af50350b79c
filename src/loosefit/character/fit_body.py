"""anny's phenotype fitted to a character's mesh, or the misfit measured and refused.

Both bodies are compared in one pose: the character's first frame, and anny posed by the
same frame retargeted (:func:`loosefit.motion.motions.load_motion`), its hips on the
character's hips, then moved (translation only) onto the character's skin by a few
rounds of closest points. The misfit is the mean distance between the two skins, both
ways (each skin's points to the other's surface). A coordinate search over anny's height,
weight, proportions, gender and muscle, in halving steps, keeps the phenotype of the
smallest misfit.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import torch

from loosefit.errors import LoosefitInputError

SEARCHED = ("height", "weight", "proportions", "gender", "muscle")  # anny's, in this order
STEPS = (0.2, 0.1, 0.05, 0.025)  # the search's steps, each tried up and down


@dataclass(frozen=True)
class FitLimits:
    """How far a character's skin may lie from the fitted anny's before it is refused."""

    mean: float = 0.025  # m, the mean distance, both ways
    p90: float = 0.06  # m, the 90th percentile of the character's skin to anny's


@dataclass
class BodyFit:
    """anny's body fitted to a character.

    Attributes:
        shape: the phenotype (anny's six names).
        mean: m, the mean distance between the two skins, both ways.
        p90: m, the character's skin to anny's, 90th percentile.
        offset: (3,) m, where anny's hips sit from the character's (avatar axes).
        tried: phenotypes measured; ``seconds`` the search's time.
    """

    shape: dict
    mean: float
    p90: float
    offset: np.ndarray
    tried: int
    seconds: float

    def describe(self) -> str:
        named = ", ".join(f"{k} {self.shape[k]:.2f}" for k in SEARCHED)
        return (
            f"anny {named}: the skins {100 * self.mean:.1f} cm apart on average "
            f"(90 % of the character's within {100 * self.p90:.1f} cm), "
            f"{self.tried} bodies tried in {self.seconds:.1f} s"
        )


def skin_distance(a_vertices, a_faces, b_vertices, b_faces, samples: int = 3000):
    """The distances of each skin's points (at most ``samples``, evenly taken) to the other's
    surface: (a to b, b to a)."""
    from loosefit.geometry.query import closest_points

    def every(v):
        return v[:: max(1, len(v) // samples)]

    ab = closest_points(b_vertices, b_faces, every(a_vertices), max_distance=10.0).distance
    ba = closest_points(a_vertices, a_faces, every(b_vertices), max_distance=10.0).distance
    return ab, ba


def fit_body(
    character_vertices: np.ndarray,
    character_faces: np.ndarray,
    character_hips: np.ndarray,
    rotations: np.ndarray,
    avatar,
    *,
    limits: FitLimits = FitLimits(),
    source: str = "character",
) -> BodyFit:
    """anny's phenotype whose skin lies closest to the character's, in one pose.

    Args:
        character_vertices: (V, 3) the character's skin in that pose, avatar axes (m, Z up).
        character_faces: (F, 3) its triangles.
        character_hips: (3,) its hips joint there.
        rotations: (J, 3, 3) anny's joint rotations of that pose (the frame retargeted).
        avatar: the trained body (its rig; the search starts from its shape).
        limits: the misfit refused.
        source: the file, for messages.

    Raises:
        LoosefitInputError: the best misfit above ``limits``, with what was measured.
    """
    t0 = time.perf_counter()
    model = avatar.model
    faces = avatar.faces.cpu().numpy()
    rot = torch.as_tensor(rotations, dtype=avatar.dtype)[None]
    pose = avatar._pose_parameters(rot, torch.zeros(1, 3, dtype=avatar.dtype))
    target = np.asarray(character_vertices, np.float64)
    cache: dict[tuple, tuple[float, np.ndarray, np.ndarray]] = {}

    def misfit(shape: dict) -> float:
        key = tuple(round(shape[k], 4) for k in sorted(shape))
        if key not in cache:
            with torch.no_grad():
                out = model(pose_parameters=pose, phenotype_kwargs=shape)
            v = out["vertices"][0].double().cpu().numpy()
            v = v + (character_hips - out["bone_poses"][0, 0, :3, 3].double().cpu().numpy())
            shift = np.zeros(3)
            for _ in range(3):  # translation only, onto the character's skin
                from loosefit.geometry.query import closest_points

                pts = target[:: max(1, len(target) // 2000)]
                hit = closest_points(v + shift, faces, pts, max_distance=10.0)
                shift += np.median(pts - hit.points, axis=0)
            ab, ba = skin_distance(target, character_faces, v + shift, faces)
            cache[key] = (0.5 * (ab.mean() + ba.mean()), ab, shift)
        return cache[key][0]

    best = {k: float(v) for k, v in avatar.shape.items()}
    score = misfit(best)
    for step in STEPS:
        for name in SEARCHED:
            for sign in (1.0, -1.0):
                trial = dict(best)
                trial[name] = float(np.clip(best[name] + sign * step, 0.0, 1.0))
                if trial[name] != best[name] and misfit(trial) < score:
                    best, score = trial, misfit(trial)
    key = tuple(round(best[k], 4) for k in sorted(best))
    _, ab, shift = cache[key]
    fit = BodyFit(
        shape=best,
        mean=float(score),
        p90=float(np.percentile(ab, 90)),
        offset=shift,
        tried=len(cache),
        seconds=time.perf_counter() - t0,
    )
    if fit.mean > limits.mean or fit.p90 > limits.p90:
        raise LoosefitInputError(
            source,
            "mesh",
            f"a body anny can fit: skins within {100 * limits.mean:.1f} cm on average and "
            f"90 % within {100 * limits.p90:.1f} cm",
            fit.describe(),
            hint="the character's mesh alone (no loose clothes, hair or props skinned with "
            "it), standing in its first frame, in metres (glTF); a body far outside anny's "
            "range (a creature, a child's proportions) is not supported",
        )
    return fit
