"""Data sets and sequences through the API: a simulated data set packed small enough to
share and unpacked again, verified (:mod:`loosefit.data.pack`); sequences shown in the
browser viewer (:mod:`loosefit.view`, the optional ``viewer`` extra). Each imports what it
needs when called."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

Progress = Callable[[int, int], None]  # progress(done, total)


def viewer_colourings() -> dict[str, str]:
    """The viewer's colourings: each one's name on the command line and in
    :func:`loosefit.show`'s ``colouring``, and its name in the viewer's panel (light: viser is
    imported only when a viewer starts)."""
    from loosefit.view.config import COLOURINGS

    return dict(COLOURINGS)


def pack_dataset(
    source: str | Path,
    out: str | Path,
    *,
    piece_mib: float | None = None,
    workers: int = 1,
    progress: Progress | None = None,
):
    """The data set folder ``source`` packed into ``out`` (or pieces ``out.000``, ...) of
    at most ``piece_mib`` MiB, its clips coded by ``workers`` processes and checked
    decoded (:func:`loosefit.data.pack.pack`, whose report it returns)."""
    from loosefit.data.pack import pack

    return pack(source, out, piece_mib, workers, progress=progress)


def unpack_dataset(source: str | Path, dest: str | Path, *, progress: Progress | None = None):
    """A pack (a file, its pieces' folder or their prefix) unpacked into the new or empty
    folder ``dest``, every member checked (:func:`loosefit.data.pack.unpack`, whose report
    it returns)."""
    from loosefit.data.pack import unpack

    return unpack(source, dest, progress=progress)


def read_sequences(paths: list[str], data: str | None = None, clip: str | None = None):
    """Sequence files (and a data set's clip) for the viewer: ``(sequences, labels,
    sources)`` (:func:`loosefit.view.scene.read_sequences`)."""
    from loosefit.view.scene import read_sequences as read

    return read(paths, data, clip)


def viewer_config(count: int, **fields):
    """A :class:`~loosefit.view.config.ViewerConfig` of ``fields``, checked for ``count``
    sequences before anything is posed."""
    from loosefit.view import ViewerConfig

    config = ViewerConfig(**fields)
    config.validate(count)
    return config


def open_viewer(sequences, labels, config, sources=None, *, progress: Progress | None = None):
    """The browser viewer serving ``sequences`` (:func:`loosefit.view.view`): its ``url``,
    ``port`` and ``wait()``."""
    from loosefit.view import view

    return view(sequences, labels, config, sources, progress=progress)
