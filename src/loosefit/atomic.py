"""Atomic writes: a file appears complete or not at all.

Every writer of loosefit (checkpoints, datasets, sequences, exports, pictures) writes to a
temporary name beside the target, with the target's suffix (so that format-by-suffix
writers such as ``np.savez``, ``torch.save``, matplotlib and USD still work), and renames
it over the target when the write has finished; a failed write leaves no file behind.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from loosefit.errors import LoosefitInputError


@contextmanager
def atomic_path(path: Path) -> Iterator[Path]:
    """A temporary path beside ``path`` (same suffix) that replaces it on success, and is
    removed on failure.

    Raises:
        LoosefitInputError: ``path``'s folder does not exist or is not writable.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir() or not os.access(folder, os.W_OK):
        found = "no such folder" if not folder.is_dir() else "a folder that is not writable"
        raise LoosefitInputError(path, "<file>", "a path in a writable folder", found)
    tmp = folder / f".{path.stem}.partial{path.suffix}"
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
