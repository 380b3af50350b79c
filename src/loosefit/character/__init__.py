"""A user's own character: a skinned, animated glTF, fitted with an anny body and dressed.

* :mod:`~loosefit.character.gltf_character`: the character's mesh, skin and animation
  read from its glTF (:func:`read_character`), posed frame by frame;
* :mod:`~loosefit.character.fit_body`: anny's phenotype fitted to the character's mesh
  (:func:`fit_body`), or the misfit measured and refused;
* :mod:`~loosefit.character.dress`: the trained set animated on the fitted body, the garment
  carried onto the character's own mesh and kept out of it (:func:`dress_character`);
  exports of their character with the garment, and the garment alone in their space.
"""

from loosefit.character.dress import (
    DressedCharacter,
    FittedCharacter,
    dress_character,
    fit_character,
)
from loosefit.character.fit_body import BodyFit, fit_body
from loosefit.character.gltf_character import Character, has_skinned_mesh, read_character

__all__ = [
    "BodyFit",
    "Character",
    "DressedCharacter",
    "FittedCharacter",
    "dress_character",
    "fit_body",
    "fit_character",
    "has_skinned_mesh",
    "read_character",
]
