"""loosefit: loose-fitting garment animation via a generative model of deformation decomposition.

::

    import loosefit

    model = loosefit.load()                    # the pretrained set, or a checkpoint path
    result = model.animate("dance:20")         # a .bvh/.npz file, a move, or a Motion
    result.export("dance.usdc")                # also .usda, .pc2 (+ OBJ), a folder of OBJs
"""

__version__ = "0.1.0"
__all__ = ["AnimatedGarment", "Animator", "load", "simulate", "__version__"]


def __getattr__(name: str):
    """The API, imported on first use (``import loosefit`` stays light)."""
    if name in ("load", "simulate", "Animator"):
        from loosefit import api

        return getattr(api, name)
    if name == "AnimatedGarment":
        from loosefit.sequence import AnimatedGarment

        return AnimatedGarment
    raise AttributeError(f"module 'loosefit' has no attribute {name!r}")
