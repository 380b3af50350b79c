"""Fitting a motion stage's residual process (:mod:`loosefit.model.residual`).

The motion stage is rolled out, free-running from the settled drape as at inference,
through every training clip of a data set; the simulated garment less the rolled-out one,
both in the root frame, is each frame's residual; the process is their leading principal
directions. Seconds a clip on one core, no gradient: the weights of the motion stage are
not touched. The file written (``residual.pt``) sits beside the set's ``motion.pt``, which
takes it when loaded (:class:`~loosefit.inference.animator.AnimationModel`).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch

from loosefit.errors import LoosefitInputError
from loosefit.model.motion_features import to_root_frame
from loosefit.model.residual import ResidualConfig, ResidualProcess, fit_residual_process


def clip_residuals(model, seq) -> torch.Tensor:
    """(T, V, 3) one clip's residuals: its simulated garment less the motion stage's
    rollout (:class:`~loosefit.inference.animator.AnimationModel`, every later stage off),
    in each frame's root frame."""
    from loosefit.inference.stages import MOTION_ONLY

    rolled = model.animate(seq.motion, stages=MOTION_ONLY).vertices
    _, H, p, P = model.motion_stage().inputs(seq.motion)
    H, p = H[P:].cpu(), p[P:].cpu()
    truth = torch.as_tensor(np.asarray(seq.garment_vertices), dtype=torch.float32)
    if truth.shape != rolled.shape:
        raise LoosefitInputError(
            seq.name, "garment_vertices", f"shape {tuple(rolled.shape)}", tuple(truth.shape)
        )
    return to_root_frame(truth, H, p) - to_root_frame(torch.as_tensor(rolled), H, p)


def fit_gain(
    model, data: str | Path, clips: list[str], log: Callable[[str], None] = print
) -> tuple[tuple[float, float], dict]:
    """The gain (a, b) of the residual process on the motion's intensity: the least-squares
    line through the motion stage's per-frame error (its rollout against the simulation,
    RMS over the vertices) against the motion's intensity w_t
    (:func:`~loosefit.model.residual.motion_intensity`) over ``clips``, divided by the
    error's mean, so that m_t is 1 on average over them.

    Args:
        model: an :class:`~loosefit.inference.animator.AnimationModel`.
        data: the data set; ``clips``: clips of it the motion stage was not trained on.
        log: where each clip's line goes.

    Returns:
        (a, b), and the fit's record (clips, frames, the line in cm and cm per rad/s, the
        correlation of error and intensity).
    """
    from loosefit.data.format import DatasetReader
    from loosefit.eval.metrics import rmse_per_frame
    from loosefit.inference.stages import MOTION_ONLY
    from loosefit.model.residual import motion_intensity

    if not clips:
        raise LoosefitInputError(Path(data), "clips", "at least one clip for the gain", "none")
    reader = DatasetReader(data)
    errors, speeds = [], []
    for name in clips:
        seq = reader.read(name)
        rolled = model.animate(seq.motion, stages=MOTION_ONLY).vertices
        errors.append(rmse_per_frame(rolled, seq.garment_vertices))
        speeds.append(motion_intensity(seq.motion.rotations, seq.motion.fps))
        log(f"[residual] gain: {name}, error {100 * errors[-1].mean():.2f} cm")
    e, w = np.concatenate(errors), np.concatenate(speeds)
    slope, intercept = np.polyfit(w, e, 1)
    mean = float(e.mean())
    gain = (float(intercept / mean), float(slope / mean))
    record = {
        "clips": list(clips),
        "frames": int(len(e)),
        "error_cm": [100 * float(intercept), 100 * float(slope)],
        "correlation": float(np.corrcoef(w, e)[0, 1]),
    }
    return gain, record


def fit_residual(
    model,
    data: str | Path,
    config: ResidualConfig | None = None,
    *,
    split: str = "train",
    gain_clips: list[str] | None = None,
    log: Callable[[str], None] = print,
) -> tuple[ResidualProcess, dict]:
    """The residual process of ``model``'s motion stage over a data set's split.

    Args:
        model: an :class:`~loosefit.inference.animator.AnimationModel`.
        data: a data set simulated on the model's garment and body.
        config: the process's size, memory and scale (default :class:`ResidualConfig`).
        split: the clips it is fitted on.
        gain_clips: clips the motion stage was not trained on, to fit the spread's gain on
            the motion's intensity (:func:`fit_gain`); None: the same spread every frame.
        log: where each clip's line goes.

    Returns:
        The process, and what it was fitted on (data set, clips, frames, the residuals'
        RMS per vertex in metres).

    Raises:
        LoosefitInputError: a data set of another garment, or too few frames.
    """
    from loosefit.data.format import DatasetReader
    from loosefit.garment.fingerprint import same_garment

    config = config or ResidualConfig()
    reader = DatasetReader(data)
    clips = reader.split(split)
    parts = []
    for name in clips:
        seq = reader.read(name)
        if not same_garment(seq.template, model.template):
            raise LoosefitInputError(
                reader.sequence_path(name),
                "garment",
                "the garment the motion stage animates",
                "another garment",
            )
        r = clip_residuals(model, seq)
        parts.append(r)
        rms = float(r.pow(2).sum(-1).mean().sqrt())
        log(f"[residual] {name}: {len(r)} frames, residual {100 * rms:.2f} cm")
    residuals = torch.cat(parts) if parts else torch.empty(0, model.template.num_vertices, 3)
    if len(residuals) < config.directions:
        raise LoosefitInputError(
            Path(data),
            f"split {split!r}",
            f"at least {config.directions} frames (the process's directions)",
            f"{len(residuals)} frames",
        )
    process = fit_residual_process(residuals, config)
    gain_record = None
    if gain_clips:
        gain, gain_record = fit_gain(model, data, gain_clips, log)
        process = process.with_gain(gain)
    record = {
        "dataset": Path(data).name,
        "split": split,
        "clips": list(clips),
        "frames": len(residuals),
        "residual_rms": float(residuals.pow(2).sum(-1).mean().sqrt()),
        "gain": gain_record,
    }
    return process, record
