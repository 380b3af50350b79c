"""The trained set on another body: the carry's pure functions, the body's preparation and
its refusals, and the pretrained set animated on a body it was not trained on."""

from __future__ import annotations

import numpy as np
import pytest
import torch

import loosefit
from loosefit.errors import LoosefitInputError
from loosefit.inference.other_body import (
    CarryConfig,
    OtherBody,
    carry_garment,
    carry_weights,
    leg_length,
    motion_on,
    nearest_anchors,
    sized_garment,
)

HEAVY = {"weight": 0.95, "height": 0.3}


def _points(n: int, seed: int) -> torch.Tensor:
    return torch.from_numpy(np.random.default_rng(seed).normal(size=(2, n, 3))).float()


def test_weights_are_a_partition_of_one_led_by_the_nearest_anchor():
    garment, anchors = _points(50, 0), _points(80, 1)
    config = CarryConfig(neighbours=6, rebind=1)
    idx = nearest_anchors(garment, anchors, config)
    w = carry_weights(garment, anchors, idx, width=0.2)
    assert idx.shape == w.shape == (2, 50, 6)
    torch.testing.assert_close(w.sum(-1), torch.ones(2, 50))
    assert torch.equal(idx[..., 0], torch.cdist(garment, anchors).argmin(-1))
    assert (w[..., 0] >= w.max(-1).values - 1e-7).all()  # the nearest weighs most


def test_the_nearest_anchors_are_found_every_few_frames_and_kept_between():
    garment, anchors = _points(30, 4).repeat(5, 1, 1)[:9], _points(40, 5).repeat(5, 1, 1)[:9]
    anchors = anchors + torch.arange(9.0)[:, None, None] * 0.3  # they move away, frame by frame
    idx = nearest_anchors(garment, anchors, CarryConfig(neighbours=3, rebind=4))
    assert idx.shape == (9, 30, 3)
    for t in range(9):
        s = t - t % 4
        want = torch.topk(torch.cdist(garment[s], anchors[s]), 3, largest=False).indices
        assert torch.equal(idx[t], want)


def test_a_body_moved_whole_moves_the_garment_whole_and_the_same_body_moves_nothing():
    garment, anchors = _points(40, 2), _points(60, 3)
    shift = torch.tensor([0.1, -0.2, 0.05])
    moved = carry_garment(garment, anchors, anchors + shift)
    torch.testing.assert_close(moved, garment + shift)
    torch.testing.assert_close(carry_garment(garment, anchors, anchors), garment)


def test_each_vertex_follows_the_skin_nearest_it():
    """Two far groups of anchors, one moved: the garment beside it follows, the other stays."""
    anchors = torch.tensor([[[0.0, 0, 0], [0.01, 0, 0], [1.0, 0, 0], [1.01, 0, 0]]])
    to = anchors.clone()
    to[0, 2:, 2] += 0.1
    garment = torch.tensor([[[0.0, 0.05, 0], [1.0, 0.05, 0]]])
    out = carry_garment(garment, anchors, to, CarryConfig(neighbours=4, rebind=1, width=0.04))
    torch.testing.assert_close(out[0, 0], garment[0, 0], atol=1e-6, rtol=0)
    torch.testing.assert_close(out[0, 1], garment[0, 1] + torch.tensor([0, 0, 0.1]))


def test_the_motion_on_a_longer_legged_body_keeps_its_feet_on_the_floor(avatar):
    from loosefit.body.avatar import Avatar, AvatarConfig
    from loosefit.motion.motions import load_motion

    tall = Avatar(AvatarConfig(shape={**avatar.shape, "height": 0.9}))
    motion = load_motion("sway", avatar).slice(0, 12)
    on = motion_on(motion, avatar, tall)
    np.testing.assert_array_equal(on.rotations, motion.rotations)
    scale = leg_length(tall) / leg_length(avatar)
    assert scale > 1.1
    np.testing.assert_allclose(on.root_translation[:, :2], motion.root_translation[:, :2] * scale)
    low = float(avatar.pose_motion(motion).vertices[..., 2].min())
    assert abs(float(tall.pose_motion(on).vertices[..., 2].min()) - low) < 0.02  # on the floor
    back = motion_on(on, tall, avatar)
    np.testing.assert_allclose(back.root_translation, motion.root_translation, atol=1e-5)


def test_the_skirt_is_made_again_for_the_body_and_an_other_garment_is_carried(avatar, skirt):
    from loosefit.body.avatar import Avatar, AvatarConfig
    from loosefit.types import GarmentTemplate

    heavy = Avatar(AvatarConfig(shape={**avatar.shape, "weight": 0.95}))
    sized = sized_garment(skirt, avatar, heavy, CarryConfig())
    assert sized.num_vertices == skirt.num_vertices
    assert sized.meta["waist_fit"]["radii"][0] > skirt.meta["waist_fit"]["radii"][0] + 0.005
    plain = GarmentTemplate(
        skirt.vertices, skirt.faces, skirt.uvs, skirt.face_uvs, skirt.waist, name="file"
    )
    carried = sized_garment(plain, avatar, heavy, CarryConfig())
    waist = skirt.waist
    r_before = np.linalg.norm(skirt.vertices[waist, :2], axis=1).mean()
    r_after = np.linalg.norm(carried.vertices[waist, :2], axis=1).mean()
    r_sized = np.linalg.norm(sized.vertices[waist, :2], axis=1).mean()
    assert r_after > r_before + 0.005  # the waist moved out with the body
    assert abs(r_after - r_sized) < 0.01  # near where the pattern made for the body sits


def test_bad_bodies_are_refused_naming_the_field_and_the_names(avatar, skirt):
    with pytest.raises(LoosefitInputError, match="hair.*gender, age, muscle"):
        OtherBody.prepare({"hair": 0.5}, avatar, skirt)
    with pytest.raises(LoosefitInputError, match="'height'.*\\[0, 1\\].*1.5"):
        OtherBody.prepare({"height": 1.5}, avatar, skirt)
    with pytest.raises(LoosefitInputError, match="'weight'.*number"):
        OtherBody.prepare({"weight": "heavy"}, avatar, skirt)


@pytest.fixture(scope="module")
def pretrained():
    return loosefit.load()


def test_the_pretrained_set_animates_on_another_body_sized_seated_and_out_of_it(pretrained):
    from loosefit.geometry.edges import unique_edges
    from loosefit.geometry.query import closest_points

    on = pretrained.animate("spin", frames=10, shape=HEAVY, threads=1)
    default = pretrained.animate("spin", frames=10, threads=1)
    body = pretrained.other_body(HEAVY)
    assert on.avatar["shape"] == body.shape and body.shape["weight"] == 0.95
    assert on.vertices.shape == default.vertices.shape
    assert np.isfinite(on.vertices).all()
    assert on.garment is body.template
    assert np.abs(on.vertices - default.vertices).max() > 0.02  # not the trained body's
    posed = body.avatar.pose_motion(on.motion)
    faces = body.avatar.faces.cpu().numpy()
    for t in range(len(on.vertices)):
        skin = posed.vertices[t].cpu().numpy()
        hit = closest_points(skin, faces, on.vertices[t], max_distance=1.0)
        depth = np.where(hit.inside, hit.distance, 0.0)
        assert depth.max() < 0.005  # no vertex deeper than 5 mm
        assert hit.inside.mean() < 0.0005  # inside: under 0.05 % of the vertices
        gap = hit.distance[body.template.waist]
        assert gap.max() < 0.02  # the waistband sits on this body's waist
    edges, _ = unique_edges(body.template.faces)
    length = lambda x: np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1)  # noqa: E731
    change = length(on.vertices[-1]) / length(body.template.vertices) - 1
    assert abs(float(np.median(change))) < 0.02
    assert pretrained.other_body(dict(HEAVY)) is body  # prepared once
    gender = pretrained.model.body["shape"]["gender"]
    assert pretrained.other_body({"gender": gender}) is None  # the trained body itself


def test_a_baseline_or_feedback_cannot_change_body(pretrained):
    from loosefit.inference.stages import Stages

    with pytest.raises(LoosefitInputError, match="feedback"):
        pretrained.animate("spin", frames=4, shape=HEAVY, stages=Stages(feedback=True))


def test_cli_animate_on_another_body(tmp_path, capsys):
    from loosefit.cli import main
    from loosefit.sequence import GarmentSequence

    out = tmp_path / "a.npz"
    assert (
        main(["animate", "spin", "--frames", "6", "--shape", "height=0.8", "--out", str(out)]) == 0
    )
    seq = GarmentSequence.load(out)
    assert seq.avatar["shape"]["height"] == 0.8 and len(seq.vertices) == 6
    assert "body height=0.8: prepared" in capsys.readouterr().err
    bad = ["animate", "spin", "--frames", "6", "--shape", "height", "--out", str(out)]
    assert main(bad) != 0
    assert "--shape: field 'height': expected NAME=VALUE" in capsys.readouterr().err
