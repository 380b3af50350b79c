"""Physics ground truth: garments simulated on the moving avatar, and data sets of them.

The simulator, bottom up:

* :mod:`~loosefit.sim.cloth_config`: :class:`ClothConfig`, the physics.
* :mod:`~loosefit.sim.kernels`, :mod:`~loosefit.sim.waist`: the warp kernels, and the
  waistband glued to the moving body.
* :mod:`~loosefit.sim.stepper`: :class:`ClothSimulator`, Newton's VBD solver as a static
  model, two states and a step.
* :mod:`~loosefit.sim.overlap`, :mod:`~loosefit.sim.release`: a body that folds into
  itself made one the cloth can lie outside of, and cloth trapped inside put back.
* :mod:`~loosefit.sim.timeline`, :mod:`~loosefit.sim.resume`: a clip's body over settle,
  blend and motion; a killed run's saved state.
* :mod:`~loosefit.sim.driver`: :func:`simulate`, :func:`simulate_batch`, :func:`settle`;
  :mod:`~loosefit.sim.rest_drape`: a data set's garment settled on the rest pose.

Data sets of simulated clips:

* :mod:`~loosefit.sim.dataset_config`, :mod:`~loosefit.sim.presets`: what a data set
  holds, from a file or a named preset.
* :mod:`~loosefit.sim.jobs`: its clips; :mod:`~loosefit.sim.manifest`: its manifest and
  the migrations of older ones; :mod:`~loosefit.sim.report`: its quality table.
* :mod:`~loosefit.sim.workers`, :mod:`~loosefit.sim.cluster`: the processes (or Ray tasks)
  that simulate the clips; :mod:`~loosefit.sim.generate`: :func:`generate`, the runner.
"""
