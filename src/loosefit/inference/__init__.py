"""The runtime: trained models loaded from their checkpoints, animating garments, packaged
for sharing. Nothing here trains, and nothing here imports :mod:`loosefit.train`.

Where a frame of animation goes (``loosefit.load().animate(motion)``):

1. :mod:`~loosefit.inference.animator`: :meth:`AnimationModel.animate
   <loosefit.inference.animator.AnimationModel.animate>` checks the motion and builds the
   motion stage and the list of later stages;
2. :mod:`~loosefit.inference.timeline`: the rest pose and the blend put before the motion;
3. :mod:`~loosefit.inference.rollout`: :func:`~loosefit.inference.rollout.rollout` runs
   the motion stage frame by frame, and hands the frames to the later stages;
4. :mod:`~loosefit.inference.stages`: detail, edge lengths, collision (one module each),
   each a :class:`~loosefit.inference.stages.Stage`.

The other modules:

* :mod:`~loosefit.inference.protocols`: what a model that animates offers
  (:class:`~loosefit.inference.protocols.AnimatingModel`), ours and the baselines'
  (:mod:`~loosefit.inference.baseline`); :mod:`~loosefit.inference.model_common` what
  both share; :func:`~loosefit.inference.loader.load_model` loads any of them.
* :mod:`~loosefit.inference.references`: the carried drape and the reconstruction, the
  references error tables set a rollout against.
* :mod:`~loosefit.inference.checkpoints`: the checkpoint files and their formats; the
  generative stage.
* :mod:`~loosefit.inference.onnx`: the learned stages as ONNX graphs (export, runtime,
  the graphs the rollout calls).
* :mod:`~loosefit.inference.engine`: the engine tier (a linear garment basis and its
  recurrent step, capsules), its rollout, ONNX export and runtime.
* :mod:`~loosefit.inference.other_body`: the garment carried onto another body.
* :mod:`~loosefit.inference.package`: a trained model as a shareable folder.
"""
