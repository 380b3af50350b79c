"""The runtime: trained models loaded from their checkpoints, animating garments, packaged
for sharing. Nothing here trains, and nothing here imports :mod:`loosefit.train`.

* :mod:`~loosefit.inference.checkpoints`: the checkpoint files and their formats; the
  generative stage.
* :mod:`~loosefit.inference.animator`: :class:`~loosefit.inference.animator.AnimationModel`
  (the paper's stages), :class:`~loosefit.inference.animator.BaselineModel`, and
  :func:`~loosefit.inference.animator.load_pipeline` for any checkpoint.
* :mod:`~loosefit.inference.package`: a trained model as a shareable folder.
"""
