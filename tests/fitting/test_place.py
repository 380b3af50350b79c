import numpy as np
import torch

from loosefit.fitting.place import carry_rigidly, fit_skirt, natural_waist_height
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
    assert back.rest_vertices is None and back.rest is back.vertices  # its start is its rest
    assert (
        back.meta["style"] == "aline"
        and back.meta["config"]["rings"] == skirt.meta["config"]["rings"]
    )


def test_a_rest_shape_apart_from_the_start_goes_through_every_file(avatar, tmp_path):
    """A fitted garment's rest shape: the template file, a sequence and a checkpoint keep it."""
    import dataclasses

    from loosefit.inference.checkpoints import template_dict, template_from_dict
    from loosefit.sequence import GarmentSequence
    from loosefit.types import GarmentTemplate

    skirt = fit_skirt(avatar)
    fitted = dataclasses.replace(skirt, rest_vertices=skirt.vertices * 0.95)
    fitted.save(tmp_path / "fitted.npz")
    back = GarmentTemplate.load(tmp_path / "fitted.npz")
    np.testing.assert_array_equal(back.rest, fitted.rest_vertices)
    np.testing.assert_array_equal(template_from_dict(template_dict(fitted)).rest, back.rest)
    assert template_from_dict(template_dict(skirt)).rest_vertices is None
    motion = avatar.rest_motion(2)
    g = np.repeat(skirt.vertices[None], 2, 0)
    seq = GarmentSequence(motion, fitted, g, {"rig": "cmu_mb", "shape": {}}, "test")
    again = GarmentSequence.load(seq.save(tmp_path / "seq.npz"))
    np.testing.assert_array_equal(again.garment.rest, fitted.rest_vertices)
