"""The body: the avatar (anny, posed by a motion), its capsules for the engine tier and its
regions as cloth diagnostics see them. Motion files and retargeting: :mod:`loosefit.motion`."""
