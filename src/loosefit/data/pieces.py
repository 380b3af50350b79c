"""A pack's pieces (``OUT.000``, ``OUT.001``, ...): found, read as one file, written."""

from __future__ import annotations

import bisect
import io
import itertools
import re
from pathlib import Path

from loosefit.errors import LoosefitInputError


def find_pieces(source: str | Path) -> list[Path]:
    """The files of a pack, in order: ``source`` itself (a file), a folder of its numbered
    pieces (``OUT.000``, ``piece-000``, ...), or the pieces' common prefix (``OUT.``).

    Raises:
        LoosefitInputError: nothing there, or a gap in the numbering (naming the missing
            piece).
    """
    p = Path(source)
    if p.is_file():
        return [p]
    if p.is_dir():
        found = [
            (m.group(1), m.group(2), f)
            for f in p.iterdir()
            if not f.name.startswith(".")
            and f.is_file()
            and (m := re.fullmatch(r"(.*[.-])(\d+)", f.name))
        ]
    elif p.parent.is_dir():
        found = [
            (p.name + m.group(1), m.group(2), f)
            for f in p.parent.iterdir()
            if f.name.startswith(p.name)
            and f.is_file()
            and (m := re.fullmatch(r"([.-]?)(\d+)", f.name[len(p.name) :]))
        ]
    else:
        found = []
    if not found:
        raise LoosefitInputError(
            source,
            "<file>",
            "a pack file, a folder of its numbered "
            "pieces, or the pieces' common prefix (e.g. dance.lfz.)",
            "nothing there",
        )
    prefixes = sorted({prefix for prefix, _, _ in found})
    if len(prefixes) > 1:
        raise LoosefitInputError(
            source, "<pieces>", "the pieces of one pack", f"pieces named {', '.join(prefixes)}"
        )
    found.sort(key=lambda x: int(x[1]))
    for k, (prefix, digits, f) in enumerate(found):
        if int(digits) != k:
            missing = f.parent / f"{prefix}{k:0{len(digits)}d}"
            raise LoosefitInputError(
                missing,
                "<piece>",
                f"piece {k} of {len(found)}+ (the numbering runs 0, 1, ...)",
                "missing",
                hint="every piece of the pack is needed",
            )
    return [f for _, _, f in found]


class PieceReader(io.RawIOBase):
    """The pieces of a pack read as one seekable file."""

    def __init__(self, paths: list[Path]) -> None:
        self.paths = paths
        self.starts = list(itertools.accumulate((p.stat().st_size for p in paths), initial=0))
        self.pos, self._k, self._fh = 0, -1, None

    @property
    def size(self) -> int:
        return self.starts[-1]

    def piece_at(self, offset: int) -> Path:
        """The piece holding byte ``offset`` (the last piece past the end)."""
        k = bisect.bisect_right(self.starts, max(offset, 0)) - 1
        return self.paths[min(k, len(self.paths) - 1)]

    def readable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def tell(self) -> int:
        return self.pos

    def seek(self, offset: int, whence: int = io.SEEK_SET) -> int:
        base = {io.SEEK_SET: 0, io.SEEK_CUR: self.pos, io.SEEK_END: self.size}[whence]
        self.pos = max(base + offset, 0)
        return self.pos

    def readinto(self, b) -> int:
        if self.pos >= self.size:
            return 0
        k = bisect.bisect_right(self.starts, self.pos) - 1
        if k != self._k:
            if self._fh is not None:
                self._fh.close()
            self._fh, self._k = open(self.paths[k], "rb"), k  # noqa: SIM115 - kept open
        self._fh.seek(self.pos - self.starts[k])
        n = self._fh.readinto(memoryview(b)[: min(len(b), self.starts[k + 1] - self.pos)])
        self.pos += n
        return n

    def close(self) -> None:
        if self._fh is not None:
            self._fh.close()
        super().close()


class PieceWriter(io.RawIOBase):
    """A file written as pieces of at most ``limit`` bytes: ``folder/piece-000``, ..."""

    def __init__(self, folder: Path, limit: int | None) -> None:
        self.folder, self.limit, self.pos, self.paths, self._fh = folder, limit, 0, [], None

    def writable(self) -> bool:
        return True

    def tell(self) -> int:
        return self.pos

    def write(self, b) -> int:
        view = memoryview(b).cast("B")
        while view:
            if self._fh is None or (self.limit and self._fh.tell() >= self.limit):
                self._next()
            room = len(view) if not self.limit else self.limit - self._fh.tell()
            self._fh.write(view[:room])
            self.pos += min(room, len(view))
            view = view[room:]
        return len(b)

    def _next(self) -> None:
        if self._fh is not None:
            self._fh.close()
        self.paths.append(self.folder / f"piece-{len(self.paths):03d}")
        self._fh = open(self.paths[-1], "wb")  # noqa: SIM115 - closed by _next/close

    def close(self) -> None:
        if self._fh is not None:
            self._fh.close()
        super().close()
