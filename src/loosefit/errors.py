"""One error type for bad input, so every message names where, what, expected and found."""

from __future__ import annotations

from os import PathLike


class LoosefitInputError(ValueError):
    """Bad user input: a malformed file, a wrong shape, NaN, a missing joint.

    The message always names the source (file or argument), the field, what was
    expected and what was found, e.g.::

        61_01.bvh: field 'MOTION/Frames': expected 2242 frame lines, found 2241
    """

    def __init__(
        self,
        source: str | PathLike | None,
        field: str,
        expected: str,
        found: str,
        hint: str | None = None,
    ) -> None:
        self.source = str(source) if source is not None else "<input>"
        self.field = field
        self.expected = expected
        self.found = found
        self.hint = hint
        msg = f"{self.source}: field '{field}': expected {expected}, found {found}"
        if hint:
            msg += f" ({hint})"
        super().__init__(msg)

    def __reduce__(self):
        # raised in another process (a --workers pool, a Ray task), it arrives whole
        return type(self), (self.source, self.field, self.expected, self.found, self.hint)
