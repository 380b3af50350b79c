"""The stages after the motion stage, each one small callable over a run of frames.

A rollout (:func:`loosefit.inference.rollout.rollout`) decodes each frame's garment from
the motion stage, then hands runs of frames to a list of :class:`Stage` objects in order:

* :mod:`~loosefit.inference.stages.detail`: the detail generator's residual (paper 3.4);
* :mod:`~loosefit.inference.stages.lengths`: edges back to their rest lengths;
* :mod:`~loosefit.inference.stages.collision`: the garment pushed out of the body (paper
  3.5), and :mod:`~loosefit.inference.stages.push_out` the baselines' push-out.

:class:`Stages` is the user's switchboard (which of them run, and how); the model turns
it into the list of stage objects (:meth:`loosefit.inference.animator.AnimationModel.
later_stages`).
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from typing import Protocol

import torch


@dataclass(frozen=True)
class Stages:
    """Which stages run after the decoders (each can be switched off)."""

    detail: bool = True  # paper 3.4, when the model carries a detail stage
    lengths: bool = True  # edges back to their rest lengths (stages.lengths.LengthRestorer)
    collision: bool = True  # paper 3.5
    feedback: bool = False  # the garment after them is the next frame's previous state
    overlap: bool = True  # without feedback: they run on a second thread beside the motion stage


MOTION_ONLY = Stages(detail=False, lengths=False, collision=False)  # the motion stage alone


@dataclass
class StageFrames:
    """A run of consecutive motion frames on their way through the later stages.

    Attributes:
        vertices: (n, V, 3) float32 world garments, on the CPU.
        codes: (n, Z) the motion encoder's Z_t of those frames.
        headings: (n, 3, 3) their root frames' headings H (CPU).
        origins: (n, 3) their root frames' origins p (CPU).
        start: the motion frame of the first of them.
    """

    vertices: torch.Tensor
    codes: torch.Tensor
    headings: torch.Tensor
    origins: torch.Tensor
    start: int


class Stage(Protocol):
    """One stage after the motion stage: world garments in, world garments out."""

    name: str  # its key in RolloutResult.stage_seconds ("detail", "lengths", "collision")

    def __call__(self, frames: StageFrames) -> torch.Tensor:
        """(n, V, 3) float32 world garments (CPU) of ``frames`` after this stage."""
        ...


@dataclass
class StageClock:
    """Wall-clock and thread CPU seconds per stage, summed over a rollout.

    ``time.thread_time`` counts the CPU time of the thread that ran a stage: unlike the
    wall clock, it is not lengthened by other work on a shared machine.
    """

    seconds: dict[str, float] = field(default_factory=dict)  # wall-clock per stage name
    cpu_seconds: dict[str, float] = field(default_factory=dict)  # thread CPU per stage name

    @contextmanager
    def measure(self, name: str) -> Iterator[None]:
        """Time the block as stage ``name`` (added to what it had)."""
        t0, c0 = time.perf_counter(), time.thread_time()
        try:
            yield
        finally:
            self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - t0
            self.cpu_seconds[name] = self.cpu_seconds.get(name, 0.0) + time.thread_time() - c0

    def measured(self, names: Sequence[str]) -> tuple[dict, dict]:
        """The stages of ``names`` (in that order) that took any time: wall and CPU seconds."""
        wall = {k: self.seconds[k] for k in names if self.seconds.get(k, 0.0) > 0}
        return wall, {k: self.cpu_seconds[k] for k in wall}


def run_stages(
    stages: Sequence[Stage], frames: StageFrames, clock: StageClock | None = None
) -> torch.Tensor:
    """``frames`` through ``stages`` in order, each timed on ``clock``.

    Returns:
        (n, V, 3) float32 world garments (a new tensor: ``frames.vertices`` is not changed).
    """
    clock = clock or StageClock()
    with torch.no_grad():  # grad mode is per thread: a stage may run on a second one
        x = frames.vertices.clone()
        for stage in stages:
            with clock.measure(stage.name):
                x = stage(replace(frames, vertices=x))
    return x
