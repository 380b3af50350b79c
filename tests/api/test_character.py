"""A user's own character through the API (loosefit.api.character): the fit starts from the
loaded set's model, and the sheet is the library's, drawn with the set's anny triangles."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import torch
from PIL import Image

from loosefit.api.character import character_sheet, fit_character


def _stand_ins(tmp_path):
    """A fitted character (a tall capsule for their skin, a wider one for anny) and an
    animator whose model's body has the wider capsule's triangles."""
    from loosefit.render.geometry import capsule

    skin, faces = capsule(0.15, 1.7, 16, 16)
    anny, anny_faces = capsule(0.2, 1.5, 12, 12)
    character = SimpleNamespace(path=tmp_path / "hero.glb", faces=faces)
    fit = SimpleNamespace(describe=lambda: "fitted in 3 steps: 1.2 cm apart")
    fitted = SimpleNamespace(character=character, skin0=skin, anny0=anny, fit=fit)
    body = SimpleNamespace(faces=torch.as_tensor(anny_faces))
    animator = SimpleNamespace(model=SimpleNamespace(avatar=lambda: body))
    return fitted, animator, anny_faces


def test_the_fit_starts_from_the_set_s_model(tmp_path, monkeypatch):
    import loosefit.character

    calls = []
    monkeypatch.setattr(loosefit.character, "fit_character", lambda *a: calls.append(a) or "fit")
    _, animator, _ = _stand_ins(tmp_path)
    assert fit_character(tmp_path / "hero.glb", animator=animator) == "fit"
    assert calls == [(animator.model, tmp_path / "hero.glb")]


def test_the_sheet_is_the_library_s(tmp_path):
    from loosefit.character.sheet import character_sheet as library

    fitted, animator, anny_faces = _stand_ins(tmp_path)
    try:
        out = character_sheet(fitted, tmp_path / "ours.png", animator=animator, size=64)
    except RuntimeError as exc:
        pytest.skip(f"no headless OpenGL (EGL) context on this machine: {exc}")
    assert out == tmp_path / "ours.png"
    library(fitted, anny_faces, tmp_path / "theirs.png", 64)
    ours, theirs = (np.asarray(Image.open(tmp_path / n)) for n in ("ours.png", "theirs.png"))
    assert ours.shape[:2] == (64, 128) and np.array_equal(ours, theirs)
