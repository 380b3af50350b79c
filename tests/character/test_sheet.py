from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image

from loosefit.character.sheet import character_sheet
from loosefit.render.geometry import capsule

SIZE = 96


def _fitted(tmp_path):
    """A stand-in for a fitted character: a tall capsule for their skin, a shorter, wider
    one for the fitted anny (what the sheet reads of a FittedCharacter)."""
    skin, faces = capsule(0.15, 1.7, 16, 16)
    anny, anny_faces = capsule(0.2, 1.5, 12, 12)
    character = SimpleNamespace(path=tmp_path / "hero.glb", faces=faces)
    fit = SimpleNamespace(describe=lambda: "fitted in 3 steps: 1.2 cm apart")
    return SimpleNamespace(character=character, skin0=skin, anny0=anny, fit=fit), anny_faces


def _columns(image, colour):
    """The columns of an (H, W, 3) picture where the shaded colour shows."""
    px = image.astype(int)
    r, g, b = px[..., 0], px[..., 1], px[..., 2]
    if colour == "character":  # bluish grey
        hit = (b > r + 20) & (b > g)
    else:  # anny's orange
        hit = (r > b + 40) & (r > g)
    return np.flatnonzero(hit.any(0))


def test_the_sheet_shows_the_character_anny_and_both_from_two_sides(tmp_path):
    fitted, anny_faces = _fitted(tmp_path)
    try:
        path = character_sheet(fitted, anny_faces, tmp_path / "sheet.png", size=SIZE)
    except RuntimeError as exc:
        pytest.skip(f"no headless OpenGL (EGL) context on this machine: {exc}")
    assert path == Path(tmp_path / "sheet.png")
    image = np.asarray(Image.open(path).convert("RGB"))
    assert image.shape == (SIZE, 2 * SIZE, 3)  # front and side, side by side
    front = image[20:, :SIZE]  # below the title
    char, anny = _columns(front, "character"), _columns(front, "anny")
    # front view, left to right: the character, anny, and the two overlaid
    assert char.min() < anny.min() and anny.max() > char.max() - 5
    middle = (anny > SIZE / 3) & (anny < 2 * SIZE / 3)
    assert middle.any()
    assert not ((char > anny[middle].min()) & (char < anny[middle].max())).any()
    # overlaid (the right third), the taller character's head shows above anny's
    assert (_columns(image[:, :SIZE], "character") > 2 * SIZE / 3).any()
    side = image[:, SIZE:]  # the side view: the two sets one behind another, in the middle
    assert len(_columns(side, "anny")) and len(_columns(side, "character"))
