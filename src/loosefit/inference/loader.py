"""Every checkpoint the project writes, opened as a model that animates: the one table of
formats (:data:`CHECKPOINTS`: each format, what it is, the files that hold it, its loader)
and the one loader over it (:func:`load_model`, what :func:`loosefit.load` wraps). It sits
above the models it opens (:mod:`~loosefit.inference.animator`,
:mod:`~loosefit.inference.baseline`, :mod:`~loosefit.inference.engine.model`), which read
their files with :mod:`~loosefit.inference.checkpoints`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from loosefit.errors import LoosefitInputError
from loosefit.inference.animator import AnimationModel, load_detail_model
from loosefit.inference.baseline import BaselineModel
from loosefit.inference.checkpoints import (
    BASELINE_FORMAT,
    DETAIL_FORMAT,
    ENGINE_FORMAT,
    FORMATS,
    GENERATIVE_FORMAT,
    MOTION_FORMAT,
    RESIDUAL_FORMAT,
    check_format,
    read_checkpoint_file,
    read_file,
)
from loosefit.inference.engine.model import load_engine


def _motion_set(path: Path, data: dict, device, generative=None, detail=None):
    return AnimationModel.from_checkpoint(path, generative, detail, device, data=data)


def _detail_set(path: Path, data: dict, device, generative=None, detail=None):
    return load_detail_model(path, None, generative, device, data=data)


def _baseline(path: Path, data: dict, device, generative=None, detail=None):
    return BaselineModel.from_checkpoint(path, device, data=data)


def _engine(path: Path, data: dict, device, generative=None, detail=None):
    return load_engine(path, device, data=data)


def _generative_set(path: Path, data: dict, device, generative=None, detail=None):
    """A generative stage animates with the motion stage of its set: ``motion.pt`` beside
    it, when that records this file."""
    beside = path.parent / "motion.pt"
    if beside.is_file() and beside.resolve() != path.resolve():
        motion = read_file(beside, device)
        recorded = motion.get("generative", {}) if isinstance(motion, dict) else {}
        mine = path.parent / str(recorded.get("relative", ""))
        if motion.get("format") == MOTION_FORMAT and mine.resolve() == path.resolve():
            return _motion_set(beside, motion, device, generative or path, detail)
    raise LoosefitInputError(
        path,
        "format",
        "a checkpoint that animates (the generative stage alone decodes, it does not animate)",
        repr(GENERATIVE_FORMAT),
        hint="pass the motion stage trained on it (a set's motion.pt, a motion run's model.pt)",
    )


def _residual_set(path: Path, data: dict, device, generative=None, detail=None):
    beside = path.parent / "motion.pt"
    if beside.is_file():
        motion = read_checkpoint_file(beside, MOTION_FORMAT, device)
        return _motion_set(beside, motion, device, generative, detail)
    raise LoosefitInputError(
        path,
        "format",
        "a checkpoint that animates (a residual process adds to a motion stage)",
        repr(RESIDUAL_FORMAT),
        hint="pass the set's motion.pt, which takes the residual.pt beside it",
    )


@dataclass(frozen=True)
class CheckpointFormat:
    """One kind of checkpoint file the project writes, and what opens it."""

    format: str  # the ``format`` string the file records
    what: str  # what it is, in words
    files: str  # the files that hold it
    load: Callable  # load(path, data, device, generative=, detail=) -> an AnimatingModel


# every checkpoint the project writes: its format, what it is, its files, its loader
CHECKPOINTS: tuple[CheckpointFormat, ...] = (
    CheckpointFormat(
        GENERATIVE_FORMAT,
        "the generative stage: the garment's decoders (paper 3.2)",
        "generative.pt of a set (the pretrained set, a packaged one); model.pt and "
        "checkpoint.pt of a generative run. Opened with the motion.pt beside it",
        _generative_set,
    ),
    CheckpointFormat(
        MOTION_FORMAT,
        "the motion stage: the motion encoder (paper 3.3), with the generative stage it "
        "records and a packaged set's detail.pt beside it",
        "motion.pt of a set (the pretrained set, a packaged one); model.pt and checkpoint.pt "
        "of a motion run",
        _motion_set,
    ),
    CheckpointFormat(
        DETAIL_FORMAT,
        "the detail stage (paper 3.4), with the motion stage it records",
        "detail.pt of a packaged set; model.pt and checkpoint.pt of a detail run",
        _detail_set,
    ),
    CheckpointFormat(
        BASELINE_FORMAT,
        "a baseline (a skinning network, no generative stage)",
        "model.pt and checkpoint.pt of a baseline run",
        _baseline,
    ),
    CheckpointFormat(
        ENGINE_FORMAT,
        "the engine tier: a small network and a garment basis, for game engines",
        "engine.pt of a set (the pretrained set); model.pt and checkpoint.pt of an engine run",
        _engine,
    ),
    CheckpointFormat(
        RESIDUAL_FORMAT,
        "a motion stage's residual process: its seeded realisations of the cloth",
        "residual.pt of a set (the pretrained set, a packaged one). Opened with the "
        "motion.pt beside it",
        _residual_set,
    ),
)


def accepted_formats() -> str:
    """The formats :func:`load_model` opens, in words."""
    return "; ".join(f"{row.format!r} ({row.what.split(':')[0]})" for row in CHECKPOINTS)


def model_file(path: str | Path) -> Path:
    """The file :func:`load_model` opens for ``path``: the file itself, or a set's folder's
    ``motion.pt`` (the pretrained set, a packaged one), else its ``engine.pt``."""
    path = Path(path)
    if path.is_dir():
        for name in ("motion.pt", "engine.pt"):
            if (path / name).is_file():
                return path / name
        raise LoosefitInputError(
            path, "<folder>", "a set's folder (motion.pt or engine.pt in it)", "neither in it"
        )
    return path


def load_model(path: str | Path, device="cpu", generative=None, detail=None):
    """Any checkpoint of :data:`CHECKPOINTS` (or a set's folder) as a model that animates
    (an :class:`~loosefit.inference.protocols.AnimatingModel`), every file read once.

    Args:
        path: the checkpoint, or a set's folder.
        device: where to put the networks.
        generative: the generative checkpoint a motion or detail stage was trained on, if
            not the one it records.
        detail: a detail checkpoint to attach to a motion stage.

    Raises:
        LoosefitInputError: a missing or unreadable file, or one of a format not in the
            table (naming the file, the format found and the formats accepted).
    """
    path = model_file(path)
    try:
        data = read_file(path, device)
    except LoosefitInputError as exc:  # not a torch file: say what would do
        if exc.hint is not None or not path.is_file():
            raise
        hint = f"loosefit.load opens {accepted_formats()}"
        raise LoosefitInputError(path, exc.field, exc.expected, exc.found, hint=hint) from exc
    found = data.get("format") if isinstance(data, dict) else None
    row = next((r for r in CHECKPOINTS if r.format == found), None)
    if row is None:
        kinds = [f for f in FORMATS if str(found).startswith(f.rpartition("/")[0] + "/")]
        if isinstance(found, str) and kinds:
            check_format(path, data, kinds[0])  # another version: upgrade or repackage
        found = found if isinstance(found, str) or found is None else repr(found)
        raise LoosefitInputError(
            path,
            "format",
            f"a checkpoint loosefit animates with: {accepted_formats()}",
            repr(found) if found is not None else "no format (not a loosefit checkpoint)",
        )
    return row.load(path, data, device, generative=generative, detail=detail)
