"""Physics ground truth: garments simulated on the moving avatar.

* :mod:`loosefit.sim.cloth`: a garment template on an avatar driven by a
  :class:`~loosefit.types.Motion`, with Newton's Vertex Block Descent cloth
  solver (:func:`~loosefit.sim.cloth.simulate`), and per-frame quality numbers
  for any garment sequence (:func:`~loosefit.eval.quality.quality`).
"""
