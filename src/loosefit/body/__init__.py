"""The body: BVH reading, rotations, resampling, the avatar and retargeting."""
