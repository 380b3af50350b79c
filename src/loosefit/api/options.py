"""The options a run of a trained model shares through the API: which stages run after the
decoders, how many torch threads it animates with, and how an animation is exported.

::

    from loosefit.api.options import export_config, stages, torch_threads

    with torch_threads(2) as chosen:             # chosen.count == 2, chosen.why "asked"
        result = model.animate("dance:5", stages=stages(collision=False))
    result.export("dance.usdc", config=export_config(up_axis="Y"))

Each function imports what it needs when called, so that importing this module stays quick
(the commands read :func:`most_threads` while their parser is built).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass


def stages(
    *, detail: bool = True, lengths: bool = True, collision: bool = True, feedback: bool = False
):
    """Which stages run after the decoders, as :meth:`loosefit.api.Animator.animate` takes
    them (a :class:`~loosefit.inference.stages.Stages`).

    Args:
        detail: the detail stage (paper 3.4), when the model carries one.
        lengths: every hanging edge back to its rest length.
        collision: collision handling (paper 3.5).
        feedback: feed the garment after those stages back as the next frame's previous
            state (default: the decoders' output, as in training).
    """
    from loosefit.inference.stages import Stages

    return Stages(detail=detail, lengths=lengths, collision=collision, feedback=feedback)


def most_threads() -> int:
    """The most torch threads the default policy animates with
    (:data:`~loosefit.inference.threads.MOST_THREADS`)."""
    from loosefit.inference.threads import MOST_THREADS  # no torch: the standard library

    return MOST_THREADS


@dataclass
class ThreadChoice:
    """The torch threads a block animates with, and who chose them.

    Attributes:
        count: torch's intra-op threads within the block.
        asked: the count asked for, or None (the default policy chose).
        variable: the environment variable that set torch's count (``OMP_NUM_THREADS``,
            ``MKL_NUM_THREADS``), or None.
    """

    count: int
    asked: int | None
    variable: str | None


@contextmanager
def torch_threads(threads: int | None = None, *, source: str = "threads") -> Iterator[ThreadChoice]:
    """Within the block, torch's intra-op threads as ``threads`` asks (None: the free
    cores by the machine's load average, at most :func:`most_threads`; torch's own count
    where ``OMP_NUM_THREADS`` or ``MKL_NUM_THREADS`` is set); torch's count before comes
    back after it (:func:`~loosefit.inference.threads.inference_threads`,
    docs/use/THREADS.md).

    Args:
        threads: an int >= 1, or None.
        source: the option's name in a refusal (e.g. ``"--threads"``).

    Yields:
        :class:`ThreadChoice`: the count and who chose it.

    Raises:
        LoosefitInputError: ``threads`` not a whole number >= 1.
    """
    from loosefit.inference.threads import inference_threads, user_thread_variable

    with inference_threads(threads, source) as n:
        yield ThreadChoice(n, threads, user_thread_variable(os.environ))


def export_config(*, up_axis: str | None = None, skinned_body: bool = True):
    """How an animation is exported, as :meth:`loosefit.AnimatedGarment.export` takes it
    (a :class:`~loosefit.export.ExportConfig`).

    Args:
        up_axis: ``"Y"`` or ``"Z"``; None: the format's own (USD Z up; Alembic, PC2 and
            OBJ Y up; glTF is always Y up).
        skinned_body: the body as a skinned mesh where the format has one (USD, glTF),
            else as a point cache (every vertex every frame).
    """
    from loosefit.export import ExportConfig

    return ExportConfig(up_axis=up_axis, skinned_body=skinned_body)
