"""The training stages through the API: a stage's configuration from a preset, and each
stage trained on a data set into a run folder (:mod:`loosefit.train`, imported when a
function is called: loading and animating never import it).

::

    from loosefit.api import train_generative, training_config

    config = training_config("generative", "cpu", epochs=10)
    report = train_generative(config, "data/dance", "runs/generative")
"""

from __future__ import annotations

from pathlib import Path

TRAINING_STAGES = ("generative", "motion", "detail", "baseline", "engine")  # what trains


def training_config(stage: str, preset: str, **overrides):
    """A training stage's configuration (a :class:`~loosefit.train.loop.TrainerConfig`):
    the preset ``preset`` (``cpu``, ``paper``, ...) with ``overrides`` (its fields, and
    the stage's own preset arguments, e.g. ``decoder=`` or ``method=``).

    Raises:
        LoosefitInputError: a stage not in :data:`TRAINING_STAGES`, or a preset or field
            the stage has not.
    """
    if stage == "generative":
        from loosefit.train.generative import TrainGenerativeConfig as Config
    elif stage == "motion":
        from loosefit.train.motion import TrainMotionConfig as Config
    elif stage == "detail":
        from loosefit.train.detail import TrainDetailConfig as Config
    elif stage == "baseline":
        from loosefit.train.baseline import TrainBaselineConfig as Config
    elif stage == "engine":
        from loosefit.train.engine import TrainEngineConfig as Config
    else:
        from loosefit.errors import LoosefitInputError

        raise LoosefitInputError("training", "stage", " or ".join(TRAINING_STAGES), repr(stage))
    return Config.preset(preset, **overrides)


def train_generative(config, data: str | Path, out: str | Path, *, log=print, progress=True):
    """Train (or resume) the generative stage on a data set into ``out``
    (:func:`loosefit.train.generative.train_generative`); its report."""
    from loosefit.train.generative import train_generative as run

    return run(data, out, config, log=log, progress=progress)


def train_motion(
    config,
    data: str | Path,
    generative: str | Path,
    out: str | Path,
    *,
    log=print,
    progress=True,
    rest_state=None,
    settle: bool = True,
):
    """Train (or resume) the motion stage on a data set and a trained generative stage
    (:func:`loosefit.train.motion.train_motion`); its report. ``rest_state``: the settled
    drape to start rollouts from (default: the data set's); ``settle``: a data set simulated
    before the simulator recorded its drape has one settled here, once
    (:func:`~loosefit.sim.rest_drape.settled_rest_drape`)."""
    from loosefit.train.motion import train_motion as run

    settled = None
    if settle:
        from loosefit.sim.rest_drape import settled_rest_drape as settled
    return run(
        data,
        generative,
        out,
        config,
        log=log,
        progress=progress,
        rest_state=rest_state,
        settle=settled,
    )


def train_detail(
    config,
    data: str | Path,
    motion: str | Path,
    out: str | Path,
    *,
    generative: str | Path | None = None,
    log=print,
    progress=True,
):
    """Train (or resume) the detail stage on a frozen motion stage's rollouts
    (:func:`loosefit.train.detail.train_detail`; ``generative``: if not the one the motion
    stage records); its report."""
    from loosefit.train.detail import train_detail as run

    return run(data, motion, out, config, generative, log=log, progress=progress)


def train_baseline(config, data: str | Path, out: str | Path, *, log=print, progress=True):
    """Train (or resume) a baseline on a data set
    (:func:`loosefit.train.baseline.train_baseline`); its report."""
    from loosefit.train.baseline import train_baseline as run

    return run(data, out, config, log=log, progress=progress)


def train_engine(
    config, data: str | Path, motion: str | Path, out: str | Path, *, log=print, progress=True
):
    """Train (or resume) the engine tier of a full model (``motion``: its motion stage's
    checkpoint) on its data set (:func:`loosefit.train.engine.train_engine`); its report."""
    from loosefit.train.engine import train_engine as run

    return run(data, motion, out, config, log=log, progress=progress)


def fit_residual(
    motion: str | Path,
    data: str | Path,
    out: str | Path | None = None,
    *,
    directions: int = 8,
    correlation: float = 0.97,
    scale: float = 1.0,
    gain: bool = True,
    log=print,
) -> Path:
    """Fit a motion stage's residual process (:mod:`loosefit.model.residual`) on a data
    set's training clips and write it (``out``, default ``residual.pt`` beside ``motion``,
    which a packaged set's ``motion.pt`` then takes when loaded).

    Args:
        motion: the motion stage's checkpoint (a set's ``motion.pt``, a run's ``model.pt``).
        data: the data set it was trained on.
        out: the file to write.
        directions, correlation, scale: :class:`~loosefit.model.residual.ResidualConfig`.
        gain: the spread following the motion's intensity, fitted on the data set's
            validation clips (those it simulated and its split leaves out), where it has
            any; False, or none there: the same spread every frame.
        log: where each clip's line goes.

    Returns:
        The file written.

    Raises:
        LoosefitInputError: a bad configuration, a data set of another garment, too few
            training frames for ``directions``.
    """
    from loosefit.data.format import DatasetReader
    from loosefit.eval.heldout import validation_clips
    from loosefit.inference.animator import load_animation_model
    from loosefit.inference.checkpoints import save_atomic
    from loosefit.inference.residual import residual_record
    from loosefit.model.residual import ResidualConfig
    from loosefit.train.residual import fit_residual as fit

    config = ResidualConfig(directions, correlation, scale)  # refused before the work
    # the motion stage alone: a residual.pt beside it (even a stale one) is not read
    model = load_animation_model(motion)
    clips = validation_clips(DatasetReader(data)) if gain else []
    if gain and not clips:
        log("[residual] no validation clips in the data set: the same spread every frame")
    process, record = fit(model, data, config, gain_clips=clips or None, log=log)
    path = Path(out) if out is not None else Path(motion).parent / "residual.pt"
    save_atomic(residual_record(model, process, record), path)
    return path


def process_rank() -> int:
    """This process's rank in a ``torchrun`` training run (0 alone)."""
    from loosefit.train.common import distributed

    return distributed()[0]
