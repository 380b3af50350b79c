"""Garments placed on the avatar's rest body: the parametric skirt and dress made for it,
and a user's garment file converted and placed by the same rules
(:mod:`~loosefit.placement.place`). Fitting a garment made for another body, which drapes
it in the simulator, sits above the simulator in :mod:`loosefit.fit`."""
