"""An interactive 3D viewer in the browser: garment sequences on their bodies (viser).

::

    from loosefit.view import view
    viewer = view([simulated, ours], names=["simulation", "ours"])  # prints the URL
    viewer.wait()                                                   # until Ctrl-C

``loosefit view SEQUENCE [SEQUENCE ...]`` and :meth:`loosefit.AnimatedGarment.view` call
:func:`view`. The pieces: :mod:`~loosefit.view.scene` (sequences, bodies, checks),
:mod:`~loosefit.view.colouring` (per-vertex values and colour bins, pure functions),
:mod:`~loosefit.view.server` (the viser server, panel and playback) and
:mod:`~loosefit.view.headless` (headless Chromium for tests, benchmarks, screenshots).
Needs the optional extra: ``pip install 'loosefit[viewer]'``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from loosefit.view.config import COLOURINGS, LAYOUTS, ViewerConfig

if TYPE_CHECKING:  # the server imports viser (the optional extra) and warp
    from loosefit.view.server import Viewer


def view(
    sequences: Sequence,
    names: Sequence[str] | None = None,
    config: ViewerConfig | None = None,
    sources: Sequence[str] | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Viewer:
    """Serve animated garments of one garment and motion; returns the running viewer.

    Args:
        sequences: :class:`~loosefit.sequence.GarmentSequence` s (same garment, frames, fps).
        names: their labels in the panel (default: each one's ``source``).
        config: host, port, layout, colouring, ... (:class:`ViewerConfig`).
        sources: where each came from, named by errors.
        progress: the bodies' posing, ``progress(done, total)``.

    Raises:
        LoosefitInputError: sequences of other garments, frame counts or frame rates
            (naming both), or viser missing.
    """
    from loosefit.view.scene import from_animated
    from loosefit.view.server import Viewer

    return Viewer(from_animated(sequences, names, sources, progress), config)


__all__ = ["COLOURINGS", "LAYOUTS", "ViewerConfig", "view"]
