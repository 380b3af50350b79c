"""Rollouts of a trained model scored against the simulation: the paper's Table 1 and 3
figures (RMSE over the clip and per horizon, Hausdorff, STED) per clip and overall."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from loosefit.data.format import DatasetReader
from loosefit.errors import LoosefitInputError
from loosefit.eval.ensemble_members import member_clip
from loosefit.eval.metrics import hausdorff, rmse_per_frame, sted
from loosefit.garment.fingerprint import same_garment
from loosefit.inference.stages import Stages
from loosefit.sequence import GarmentSequence

HORIZONS = (100, 500, 1200)  # the paper's Table 1: iter-100, iter-500, iter-1200


def _sequences(model, data, split: str) -> Iterator[tuple[str, GarmentSequence]]:
    """(name, sequence) of a dataset's split or of given sequences, checked to be of the
    model's garment."""
    if isinstance(data, DatasetReader):
        if not same_garment(model.template, data.template):
            raise LoosefitInputError(
                data.root / "template.npz",
                "garment",
                f"the garment {model.path.name} was trained on",
                "another garment",
            )
        names = data.split(split)
        for name in names:
            clip, seed = member_clip(name)
            if seed is not None and clip in names:
                continue  # another member of a clip scored here (loosefit.eval.ensemble)
            yield name, data.read(name)
        return
    for name, seq in data.items():
        if not same_garment(model.template, seq.template):
            raise LoosefitInputError(
                name,
                "garment",
                f"the garment {model.path.name} was trained on ('{model.template.name}')",
                f"'{seq.template.name}'",
            )
        yield name, seq


def evaluate_rollouts(
    model,
    data: DatasetReader | dict[str, GarmentSequence],
    split: str = "test",
    *,
    horizons: tuple[int, ...] = HORIZONS,
    surface: bool = True,
    max_frames: int | None = None,
    reference: bool = False,
    restart_every: int | None = None,
    oracle: bool = False,
    stages: Stages | None = None,
) -> dict:
    """Roll every clip of a split out from its first frame and compare with the simulation.

    Args:
        model: the trained stages (:func:`loosefit.load`'s ``.model``).
        data: a dataset, or named sequences (the ground truth of each motion, e.g.
            from :func:`loosefit.simulate`).
        split: "train", "test" or "all" (of a dataset).
        horizons: report the RMSE over the first h frames for each h (the paper's
            iter-100/500/1200); a clip shorter than h gives none for it.
        surface: also Hausdorff and STED (slower).
        max_frames: roll out at most this many frames per clip.
        reference: score the settled drape carried by the root (the model's
            ``carry_drape``) instead of its rollout.
        restart_every: reset the rollout's previous state to the simulated garment
            every this many frames (:class:`~loosefit.inference.rollout.RestartFromTruth`),
            to measure drift on the same frames.
        oracle: score the generative model's reconstruction of the simulated
            garment (the model's ``reconstruct``) instead: the floor under the motion
            encoder's error.
        stages: the stages after the decoders (default: the model's, all of them).

    Returns:
        Per clip: frames, RMSE (cm) over the clip and per horizon, the RMSE of
        every frame (cm), Hausdorff (cm, mean over frames), STED, frames per
        second; and frame-weighted means over the clips.
    """
    clips = {}
    for name, seq in _sequences(model, data, split):
        faces = seq.template.faces
        motion = seq.motion if max_frames is None else seq.motion.slice(0, max_frames)
        true = seq.garment_vertices[: motion.num_frames]
        if reference:
            result = model.carry_drape(motion)
        elif oracle:
            result = model.reconstruct(motion, true)
        elif restart_every is not None:
            result = model.animate(motion, truth=true, restart_every=restart_every, stages=stages)
        else:
            result = model.animate(motion, stages=stages)
        pred = result.vertices
        per_frame = 100 * rmse_per_frame(pred, true)  # (T,) cm
        entry = {
            "frames": int(len(pred)),
            "rmse_cm": float(np.sqrt(np.mean(per_frame**2))),
            "horizons": {
                str(h): float(np.sqrt(np.mean(per_frame[:h] ** 2)))
                for h in horizons
                if len(pred) >= h
            },
            "rmse_per_frame_cm": per_frame.tolist(),
            "frames_per_second": result.frames_per_second,
        }
        if surface:
            entry["hausdorff_cm"] = 100 * float(hausdorff(pred, true, faces).mean())
            entry["sted"] = sted(pred, true, faces)["sted"] if len(pred) > 1 else 0.0
        clips[name] = entry
    n = np.array([c["frames"] for c in clips.values()], float)

    def mean(key: str) -> float:
        return float((np.array([c[key] for c in clips.values()]) * n).sum() / n.sum())

    summary = {
        "frames": int(n.sum()),
        "rmse_cm": float(
            np.sqrt(sum(c["rmse_cm"] ** 2 * c["frames"] for c in clips.values()) / n.sum())
        ),
    }
    if surface:
        summary.update(hausdorff_cm=mean("hausdorff_cm"), sted=mean("sted"))
    summary["horizons"] = {}
    for h in horizons:
        have = [c for c in clips.values() if str(h) in c["horizons"]]
        if have:
            summary["horizons"][str(h)] = float(
                np.sqrt(np.mean([c["horizons"][str(h)] ** 2 for c in have]))
            )
    return {"split": split, "clips": clips, **summary}
