"""A user's own character through the API: anny's body fitted to a skinned, animated
``.glb``/``.gltf`` (the phenotype found, how far the skins lie apart), and a sheet of the
two side by side. Dressing the character is :meth:`loosefit.api.Animator.dress`.

::

    import loosefit
    from loosefit.api.character import character_sheet, fit_character

    animator = loosefit.load()
    fitted = fit_character("hero.glb", animator=animator)
    print(fitted.fit.describe())
    character_sheet(fitted, "hero_fit.png", animator=animator)

Each function imports what it needs when called.
"""

from __future__ import annotations

from pathlib import Path


def fit_character(path: str | Path, *, animator):
    """The character of ``path`` read at the model's frame rate and anny's body fitted to
    it, starting from the body the model was trained on
    (:func:`loosefit.character.fit_character`): a
    :class:`~loosefit.character.dress.FittedCharacter` (``character`` its mesh, skin and
    animation; ``fit`` the phenotype found and the misfit, ``fit.describe()`` in words;
    ``hips`` the character's joint anny's hips follow).

    Args:
        path: a ``.glb`` or ``.gltf`` with a skinned mesh and an animation.
        animator: the trained model (:func:`loosefit.load`) whose body the fit starts from.

    Raises:
        LoosefitInputError: a file with no mesh, skin or animation; a character anny cannot
            fit (the misfit measured).
    """
    from loosefit.character import fit_character as fit

    return fit(animator.model, path)


def character_sheet(fitted, out: str | Path, *, animator, size: int = 480) -> Path:
    """A PNG at ``out`` (its folder must exist) of the character | the fitted anny | both
    overlaid, front and side views, first frame
    (:func:`loosefit.character.sheet.character_sheet`).

    Args:
        fitted: what :func:`fit_character` returned.
        out: the PNG to write.
        animator: the model it was fitted with (anny's triangles come from its body).
        size: pixels per view (square).

    Returns:
        the PNG's path.
    """
    from loosefit.character.sheet import character_sheet as sheet

    return sheet(fitted, animator.model.avatar().faces.cpu().numpy(), out, size)
