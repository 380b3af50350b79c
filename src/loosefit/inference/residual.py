"""A motion stage's residual process on disk: ``residual.pt`` beside a set's ``motion.pt``
(:mod:`loosefit.model.residual`), its record written and read back, checked to belong to
the motion stage and garment it was fitted to."""

from __future__ import annotations

from pathlib import Path

from loosefit.errors import LoosefitInputError
from loosefit.inference.checkpoints import (
    RESIDUAL_FORMAT,
    check_fingerprints,
    checkpoint_fields,
    read_checkpoint_file,
    stage_fingerprints,
)
from loosefit.model.residual import ResidualProcess


def attach_residual(model, path: str | Path, data: dict | None = None):
    """Load a residual process into ``model`` (an ``AnimationModel``: ``model.residual``),
    checked to belong to it; returns ``model``.

    Raises:
        LoosefitInputError: not a residual checkpoint, or one fitted to another garment or
            motion stage (the message names both fingerprints).
    """
    path = Path(path)
    data = read_checkpoint_file(path, RESIDUAL_FORMAT, model.device, data=data)
    with checkpoint_fields(path, "residual checkpoint"):
        check_fingerprints(model, path, data, "a residual process fitted to")
        process = ResidualProcess.from_dict(data["process"], str(path))
    if process.num_vertices != model.template.num_vertices:
        raise LoosefitInputError(
            path, "process.basis", f"{model.template.num_vertices} vertices", process.num_vertices
        )
    model.residual = process
    return model


def residual_record(model, process: ResidualProcess, fitted_on: dict) -> dict:
    """A residual checkpoint's contents: the process, the stages it belongs to (``model``'s,
    an ``AnimationModel``), what it was fitted on (data set, clips, frames, and how its
    scale was chosen)."""
    return {
        "format": RESIDUAL_FORMAT,
        "fingerprints": stage_fingerprints(model),
        "process": process.to_dict(),
        "fitted_on": dict(fitted_on),
    }
