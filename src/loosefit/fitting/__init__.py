"""Garments fitted to the avatar, in one place: the parametric skirt and dress made for its
body and a user's garment file converted and placed by the same rules (:mod:`.place`);
a garment made for another body draped onto it in the simulator (:mod:`.drape`, a layer
above the rest: it uses the runtime's collision handling and the simulator, which itself
places garments with :mod:`.place`)."""
