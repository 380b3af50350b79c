import numpy as np
import torch

from loosefit.dress import carry_rigidly, fit_skirt, natural_waist_height
from loosefit.garment.skirt import SkirtConfig
from loosefit.geometry.query import closest_points


def test_waist_is_between_hips_and_chest(avatar):
    z = natural_waist_height(avatar) + avatar.floor_height
    assert 0.95 < z < 1.2


def test_skirt_fits_the_waist_and_clears_the_body(avatar):
    for style in ("aline", "flared", "circle"):
        skirt = fit_skirt(avatar, SkirtConfig.preset("cpu", style))
        hit = closest_points(avatar.rest_vertices.numpy(), avatar.faces.numpy(), skirt.vertices)
        assert not hit.inside.any(), f"{style}: {hit.inside.sum()} skirt vertices inside the body"
        waist = hit.distance[skirt.waist]
        # The waistband hugs the body: within a few centimetres all round.
        assert waist.max() < 0.05, f"{style}: waistband {waist.max():.3f} m from the body"


def test_rigid_carry_follows_the_hips(avatar):
    skirt = fit_skirt(avatar)
    motion = avatar.rest_motion(2)
    motion.root_translation[1] += np.array([0.3, 0.0, 0.0], np.float32)
    body = avatar.pose_motion(motion)
    g = carry_rigidly(skirt, body, avatar)
    assert g.shape == (2, skirt.num_vertices, 3)
    assert torch.allclose(g[1] - g[0], torch.tensor([0.3, 0.0, 0.0]).expand_as(g[0]), atol=1e-5)


def test_template_file_keeps_meta(avatar, tmp_path):
    from loosefit.types import GarmentTemplate

    skirt = fit_skirt(avatar)
    skirt.save(tmp_path / "skirt.npz")
    back = GarmentTemplate.load(tmp_path / "skirt.npz")
    assert np.array_equal(back.vertices, skirt.vertices)
    assert (
        back.meta["style"] == "aline"
        and back.meta["config"]["rings"] == skirt.meta["config"]["rings"]
    )
