"""Motion: capture files read (BVH, glTF, SMPL arrays), any skeleton matched and retargeted
onto the avatar, checked and corrected (:mod:`.pose_check`, :mod:`.pose_correction`),
resampled, mirrored and chained; procedural dances; one entry point, :mod:`.motions`."""
