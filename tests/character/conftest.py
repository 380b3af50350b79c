"""The character the tests dress: anny of another phenotype on a Mixamo skeleton."""

from __future__ import annotations

import pytest

from tests.character.character_file import write_character


@pytest.fixture(scope="session")
def character(tmp_path_factory):
    """(path, its anny body, its motion on that body): 16 frames of a dance."""
    return write_character(tmp_path_factory.mktemp("character") / "character.glb")


@pytest.fixture(scope="session")
def pretrained():
    import loosefit

    return loosefit.load()


@pytest.fixture(scope="session")
def dressed(pretrained, character):
    """The pretrained set's skirt on the character, its first 10 frames."""
    return pretrained.dress(character[0], frames=10, threads=1)


@pytest.fixture(scope="session")
def fitted(pretrained, character):
    """anny fitted to the character (``fit_character``)."""
    from loosefit.character import fit_character

    return fit_character(pretrained.model, character[0])
