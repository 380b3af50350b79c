"""The stepper (loosefit.sim.stepper) on the avatar."""

from __future__ import annotations

import numpy as np

from loosefit.fitting.place import fit_skirt
from loosefit.garment.skirt import SkirtConfig
from loosefit.sim.cloth_config import ClothConfig
from loosefit.sim.stepper import ClothSimulator
from loosefit.sim.timeline import limb_collider_faces

TINY_SKIRT = SkirtConfig(style="aline", rings=8, segments=24)


def test_every_body_shape_is_culled_by_the_whole_motions_box(avatar):
    # the arms' own mesh too: a box left at the first frame's body would lose its contacts
    # once the dancer has moved away from where she started
    skirt = fit_skirt(avatar, TINY_SKIRT)
    body = avatar.rest_vertices.numpy()
    faces = avatar.collider_faces(arms=False).numpy()
    config = ClothConfig.tiny()
    bounds = (body.min(0) - 5.0, body.max(0) + 5.0)
    for K in (1, 2):
        g = np.stack([skirt.vertices] * K) if K > 1 else skirt.vertices
        b = np.stack([body] * K) if K > 1 else body
        sim = ClothSimulator(
            g,
            skirt.faces,
            skirt.waist,
            b,
            faces,
            config,
            frame_dt=1 / 30,
            bounds=bounds,
            limb_faces=limb_collider_faces(avatar, config),
        )
        lower = sim.model.shape_collision_aabb_lower.numpy()
        assert lower.shape == (2 * K, 3)
        want = np.repeat(bounds[0][None] + sim.offsets, 2, 0)
        np.testing.assert_allclose(lower, want, atol=1e-5)
