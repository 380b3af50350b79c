"""loosefit: loose-fitting garment animation via a generative model of deformation decomposition.

::

    import loosefit

    model = loosefit.load()                    # the pretrained set, or a checkpoint path
    result = model.animate("dance:20")         # a .bvh/.npz file, a move, or a Motion
    result.export("dance.usdc")                # also .usda, .pc2 (+ OBJ), a folder of OBJs
    loosefit.show(result)                      # the browser viewer (any AnimatedGarment)

    fitted = loosefit.fit_garment("made_for_another.obj")  # onto the avatar
    loosefit.simulate("dance:4", fitted.template, shape=fitted.avatar.shape)  # ground truth
"""

__version__ = "0.1.0"
__all__ = [
    "AnimatedGarment",
    "Animator",
    "fit_garment",
    "load",
    "show",
    "simulate",
    "__version__",
]


def __getattr__(name: str):
    """The API, imported on first use (``import loosefit`` stays light)."""
    if name in ("load", "show", "simulate", "Animator", "AnimatedGarment"):
        from loosefit import api

        return getattr(api, name)
    if name == "fit_garment":
        from loosefit.fitting.drape import fit_garment

        return fit_garment
    raise AttributeError(f"module 'loosefit' has no attribute {name!r}")
