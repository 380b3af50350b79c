"""The viewer's settings: what :class:`~loosefit.view.server.Viewer` serves and how it starts.

Numpy-free and quick to import (the command line's parser reads the names from here).
"""

from __future__ import annotations

from dataclasses import dataclass

from loosefit.errors import LoosefitInputError

# colourings: the command line's name -> the panel's
COLOURINGS = {
    "plain": "plain",
    "error": "distance to reference",
    "strain": "edge strain",
    "inside": "inside the body",
}
LAYOUTS = ("side by side", "overlaid")


@dataclass
class ViewerConfig:
    """How the viewer serves and starts (all but host and port changeable in its panel;
    why ``pixel_ratio`` is worth setting without a GPU: docs/design/notes/viewer.md)."""

    host: str = "127.0.0.1"  # address to listen on ("0.0.0.0": every network interface)
    port: int = 8080  # the first port tried; when it is taken, the next free one (printed)
    layout: str = "side by side"  # "side by side" (along x, ``spacing`` apart) or "overlaid"
    spacing: float = 1.0  # m between sequences side by side
    colouring: str = "plain"  # a key of COLOURINGS ("error": the distance to the reference)
    reference: int = 0  # index of the sequence the distance and RMSE are measured to
    bins: int = 10  # colour steps of a colouring
    speed: float = 1.0  # playback speed, times the sequences' frame rate
    follow: bool = True  # the camera follows the shown bodies (horizontally)
    play: bool = True  # start playing
    loop: bool = True  # play again from the start at the end
    pixel_ratio: float | None = None  # canvas pixels per screen pixel, fixed; None: the browser's

    def validate(self, num_sequences: int) -> None:
        """Raises LoosefitInputError naming the field that is out of range."""
        checks = (
            ("layout", self.layout in LAYOUTS, f"one of {LAYOUTS}", self.layout),
            (
                "colouring",
                self.colouring in COLOURINGS,
                f"one of {tuple(COLOURINGS)}",
                self.colouring,
            ),
            (
                "colouring",
                self.colouring != "error" or num_sequences > 1,
                "a second sequence to measure the distance to",
                "one sequence",
            ),
            (
                "reference",
                0 <= self.reference < num_sequences,
                f"0 to {num_sequences - 1} (one of the {num_sequences} sequences)",
                self.reference,
            ),
            ("bins", 2 <= self.bins <= 64, "2 to 64", self.bins),
            ("speed", 0 < self.speed <= 4, "more than 0, at most 4", self.speed),
            ("spacing", self.spacing >= 0, "0 m or more", self.spacing),
            ("port", 0 <= self.port < 65536, "0 to 65535", self.port),
            (
                "pixel_ratio",
                self.pixel_ratio is None or 0.1 <= self.pixel_ratio <= 4,
                "None or 0.1 to 4",
                self.pixel_ratio,
            ),
        )
        for name, ok, expected, found in checks:
            if not ok:
                raise LoosefitInputError("viewer", name, expected, repr(found))
