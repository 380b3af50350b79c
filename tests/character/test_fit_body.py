"""anny's phenotype fitted to a character's skin, or refused with the misfit."""

from __future__ import annotations

import pytest

from loosefit.character.fit_body import fit_body
from loosefit.errors import LoosefitInputError
from loosefit.motion.motions import load_motion
from tests.character.character_file import SHAPE


def test_the_fit_finds_the_body_the_character_was_made_from(fitted):
    fit = fitted.fit
    assert fit.mean < 0.01 and fit.p90 < 0.02  # skins within a centimetre
    for name in ("height", "weight"):
        assert abs(fit.shape[name] - SHAPE[name]) <= 0.1, (name, fit.shape)
    assert fitted.hips == "mixamorig:Hips"
    assert "cm apart" in fit.describe()


def test_a_body_anny_cannot_fit_is_refused_with_the_measured_misfit(pretrained, character, fitted):
    wide = fitted.skin0 * [1.8, 1.8, 1.0]  # a creature twice as broad
    hips = fitted.skin0.mean(0) * [1.8, 1.8, 1.0]
    rotations = load_motion(str(character[0]), pretrained.model.avatar()).rotations[0]
    with pytest.raises(LoosefitInputError, match="cm apart on average.*no loose clothes"):
        fit_body(wide, fitted.character.faces, hips, rotations, pretrained.model.avatar())
