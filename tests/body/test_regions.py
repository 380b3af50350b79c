"""Body regions and parts from arrays: each vertex's region by its dominant bone, and the parts
of a body of two cubes (the hips, which the cloth meets, and a left hand it passes through)."""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.body.regions import REGIONS, BodyParts, vertex_regions
from loosefit.errors import LoosefitInputError
from tests.meshes import cube

NAMES = tuple(REGIONS)


def test_a_vertex_takes_the_region_of_its_dominant_bone():
    joints = ("Hips", "LowerBack", "LeftHand", "LThumb", "LeftUpLeg")
    got = vertex_regions(np.array([0, 1, 2, 3, 4, 0]), joints)
    want = [NAMES.index(r) for r in ("hips", "waist", "left hand", "left hand", "left thigh")]
    assert got.dtype == np.int64 and got.tolist() == [*want, NAMES.index("hips")]
    with pytest.raises(
        LoosefitInputError,
        match=r"expected every dominant bone in a region, found bones in none: \['Tail'\]",
    ):
        vertex_regions(np.array([0, 1]), ("Hips", "Tail"))


def _two_cubes():
    v, f = cube(0.2)
    rest = np.concatenate([v, v + [1.0, 0.0, 0.0]])  # the hand a metre to the side
    faces = np.concatenate([f, f + 8])
    region = np.repeat([NAMES.index("hips"), NAMES.index("left hand")], 8)
    return rest, faces, f, region


def _rows(faces: np.ndarray) -> set:
    return {tuple(sorted(t)) for t in np.asarray(faces).tolist()}


def test_the_parts_of_a_body_whose_collider_leaves_the_hand_out():
    rest, faces, hips, region = _two_cubes()
    parts = BodyParts.build(rest, faces, hips, region)  # the collider: the hips cube alone
    hand = np.arange(8, 16)
    np.testing.assert_array_equal(parts.colliding, np.repeat([True, False], 8))
    assert list(parts.limb_vertices) == ["left arm"]  # the only limb with vertices
    np.testing.assert_array_equal(parts.limb_vertices["left arm"], hand)
    assert parts.limb_collides == {"left arm": False}
    # the arm passes through the cloth: tested against the whole body without it
    assert _rows(parts.limb_faces["left arm"]) == _rows(hips)
    assert _rows(parts.hip_faces) == _rows(hips)
    np.testing.assert_array_equal(parts.hand_vertices[0], hand)
    assert parts.hand_vertices[1].size == 0 and parts.thigh_vertices.size == 0
    assert parts.right_thigh_faces.shape == (0, 3)
    assert parts.collides(np.arange(8)) and not parts.collides(hand)
    assert not parts.collides(np.zeros(0, np.int64))
    got, collides = parts.tested_vertices("left arm")
    assert not collides and got.tolist() == hand.tolist()  # the whole limb
    # the region of closest points: the corner of largest weight
    bary = np.array([[0.2, 0.7, 0.1], [0.1, 0.1, 0.8]])
    assert parts.face_region(faces, np.array([0, 12]), bary).tolist() == [
        NAMES.index("hips"),
        NAMES.index("left hand"),
    ]


def test_a_hand_the_cloth_meets_is_tested_on_its_skin_against_the_collider():
    rest, faces, _, region = _two_cubes()
    parts = BodyParts.build(rest, faces, faces, region)  # the collider: the whole body
    assert parts.colliding.all() and parts.limb_collides == {"left arm": True}
    got, collides = parts.tested_vertices("left arm")
    assert collides and got.tolist() == list(range(8, 16))


def test_regions_that_do_not_fit_the_body_are_refused():
    rest, faces, hips, region = _two_cubes()
    with pytest.raises(LoosefitInputError, match=r"BodyParts: field 'region'.*found shape \(15,\)"):
        BodyParts.build(rest, faces, hips, region[:15])
    with pytest.raises(LoosefitInputError, match="region"):
        BodyParts.build(rest, faces, hips, np.full(16, len(NAMES)))
