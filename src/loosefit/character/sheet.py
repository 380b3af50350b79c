"""The fitted body beside the character (``loosefit inspect-character --sheet``): the
character's own skin in its first frame, the fitted anny beside it in the same pose, and
the two overlaid, from the front and the side."""

from __future__ import annotations

from pathlib import Path

import numpy as np

CHARACTER_COLOR = (0.55, 0.62, 0.75)  # the character's skin
ANNY_COLOR = (0.85, 0.6, 0.45)  # the fitted anny's


def character_sheet(fitted, anny_faces: np.ndarray, path: str | Path, size: int = 480) -> Path:
    """A PNG of ``fitted`` (a :class:`~loosefit.character.dress.FittedCharacter`): the
    character | the fitted anny | both overlaid, front and side views."""
    from loosefit.render.clip import render_still
    from loosefit.render.renderer import RenderConfig, RenderMesh

    skin, anny = fitted.skin0, fitted.anny0
    width = float(np.ptp(skin[:, 0])) + 0.3
    faces = fitted.character.faces
    scene = [
        RenderMesh(faces, skin - [width, 0, 0], "body", color=CHARACTER_COLOR, name="character"),
        RenderMesh(anny_faces, anny, "body", color=ANNY_COLOR, name="anny"),
        RenderMesh(faces, skin + [width, 0, 0], "body", color=CHARACTER_COLOR, name="overlay"),
        RenderMesh(anny_faces, anny + [width, 0, 0], "other", color=ANNY_COLOR, name="both"),
    ]
    config = RenderConfig(views=("front", "side"), width=size, height=size, frame_counter=False)
    title = f"{Path(fitted.character.path).name}: character | fitted anny | both; "
    title += fitted.fit.describe().split(":")[0]
    render_still(scene, path, config, title=title)
    return Path(path)
