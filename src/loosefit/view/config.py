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
    """How the viewer serves and starts (all but host and port changeable in its panel).

    Attributes:
        host: the address to listen on ("127.0.0.1": this machine, and others through an
            SSH tunnel; "0.0.0.0": every network interface).
        port: the first port tried; when it is taken, the next free one (printed).
        layout: "side by side" (along x, ``spacing`` apart) or "overlaid".
        spacing: m between sequences side by side.
        colouring: a key of :data:`COLOURINGS` (``error``: the distance to the reference).
        reference: index of the sequence the distance and RMSE are measured to.
        bins: colour steps of a colouring.
        speed: playback speed, times the sequences' frame rate.
        follow: the camera follows the shown bodies (horizontally).
        play: start playing.
        loop: play again from the start at the end.
        pixel_ratio: the canvas's pixels per screen pixel, fixed (viser's ``fixedDpr``,
            put in the URL); None: the browser's own, lowered by viser while it draws
            slowly. A browser drawing WebGL in software draws a frame in about 40% less
            time at 0.5 than at viser's ratio, more with multisampling off in the browser
            (docs/use/VIEWER.md); with a GPU leave it None.
    """

    host: str = "127.0.0.1"
    port: int = 8080
    layout: str = "side by side"
    spacing: float = 1.0
    colouring: str = "plain"
    reference: int = 0
    bins: int = 10
    speed: float = 1.0
    follow: bool = True
    play: bool = True
    loop: bool = True
    pixel_ratio: float | None = None

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
