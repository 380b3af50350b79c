"""The body: BVH reading, rotations, resampling, the avatar, its regions (:mod:`.regions`)
and retargeting."""
