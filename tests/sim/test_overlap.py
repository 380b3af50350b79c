"""Limbs pressed out of the rest of the body (loosefit.sim.overlap) on the real avatar."""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.body.regions import body_parts
from loosefit.geometry.query import Surface
from loosefit.sim.overlap import flatten_overlaps


@pytest.fixture(scope="module")
def parts(avatar):
    return body_parts(avatar, arms=False)


def test_a_clear_pose_is_left_as_it_is(avatar, parts):
    rest = avatar.rest_vertices.float().cpu().numpy()[None]
    flat = flatten_overlaps(rest, parts)
    np.testing.assert_array_equal(flat.vertices, rest)
    assert flat.moved.tolist() == [0] and flat.depth.tolist() == [0.0]


def test_a_leg_pushed_into_the_body_is_pressed_back_onto_its_surface(avatar, parts):
    rest = avatar.rest_vertices.float().cpu().numpy()
    leg = parts.limb_vertices["left leg"]
    folded = rest.copy()
    folded[leg] += np.array([-0.1, 0.0, 0.0], np.float32)  # the left thigh into the right
    tested, _ = parts.tested_vertices("left leg")
    surface = Surface(folded, parts.limb_faces["left leg"])
    hit = surface.query(folded[tested])
    buried = tested[hit.inside & (hit.distance > 0.002)]
    assert len(buried) > 20 and hit.distance[hit.inside].max() > 0.03  # centimetres deep

    flat = flatten_overlaps(folded[None], parts, inset=0.002)
    out = flat.vertices[0]
    assert flat.depth[0] == pytest.approx(hit.distance[hit.inside].max(), rel=1e-5)
    # Only leg vertices moved (the left's buried ones, then the right's that the left
    # leg's pressed skin still covers), each onto the other's surface, 2 mm short of it.
    moved = np.flatnonzero(np.linalg.norm(out - folded, axis=-1) > 0)
    legs = np.concatenate([leg, parts.limb_vertices["right leg"]])
    assert set(buried) <= set(moved) <= set(legs) and flat.moved[0] == len(moved)
    # (One pass: pressing the right leg back moves the left one's skin under it by a few
    # millimetres, less than the 5 mm at which cloth counts as through the skin.)
    for limb, most in (("left leg", 0.005), ("right leg", 0.002 + 1e-4)):
        verts, _ = parts.tested_vertices(limb)
        again = Surface(out, parts.limb_faces[limb]).query(out[verts])
        assert again.distance[again.inside].max(initial=0.0) <= most, limb


def test_a_data_set_made_before_flattening_was_made_without_it(tmp_path):

    from loosefit.sim.dataset_config import config_dict, normalized
    from loosefit.sim.manifest import stored_config
    from loosefit.sim.presets import preset

    stored = normalized(config_dict(preset("tiny")))
    del stored["cloth"]["flatten_overlaps"]
    assert stored_config({"config": stored})["cloth"]["flatten_overlaps"] is False
    assert preset("salsa").cloth.flatten_overlaps is True  # new data: the fix


def test_each_frame_s_search_starts_from_the_last_and_finds_the_same(avatar, parts, monkeypatch):
    """Frame after frame a limb's queries start from the faces the last frame found: the
    same collider as searching afresh, on the device it is given."""
    import loosefit.sim.overlap as overlap

    rest = avatar.rest_vertices.float().cpu().numpy()
    leg = parts.limb_vertices["left leg"]
    frames = []
    for dx in (0.0, -0.04, -0.08, -0.1, -0.06):  # the left thigh into the right and out
        pose = rest.copy()
        pose[leg] += np.array([dx, 0.0, 0.0], np.float32)
        frames.append(pose)
    body = np.stack(frames)
    hinted = flatten_overlaps(body, parts)

    real, hints, devices = Surface.query, [], []

    class Fresh(Surface):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            devices.append(self.device)

        def query(self, queries, *args, hint=None, **kwargs):
            hints.append(hint is not None)
            return real(self, queries, *args, **kwargs)  # no hint: the whole search

    monkeypatch.setattr(overlap, "Surface", Fresh)
    fresh = flatten_overlaps(body, parts, device="cpu")
    assert any(hints) and devices == ["cpu"] * len(devices) and devices
    assert hinted.moved.sum() > 0
    np.testing.assert_array_equal(hinted.vertices, fresh.vertices)
    np.testing.assert_array_equal(hinted.depth, fresh.depth)
    np.testing.assert_array_equal(hinted.moved, fresh.moved)
