"""Left-right mirrored motions."""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.motion.mirror import (
    REFLECT,
    mirror_garment,
    mirror_motion,
    mirror_permutation,
    twin,
    vertex_twins,
)
from loosefit.motion.motions import load_motion
from loosefit.types import Motion


def test_twins_of_the_cmu_rig(avatar):
    assert twin("LeftUpLeg") == "RightUpLeg" and twin("RHipJoint") == "LHipJoint"
    assert twin("LThumb") == "RThumb" and twin("Hips") is None and twin("LowerBack") is None
    perm = mirror_permutation(avatar.joint_names)
    assert (perm[perm] == np.arange(len(perm))).all()  # swapping twice is the identity
    names = np.array(avatar.joint_names)
    central = set(names[perm == np.arange(len(perm))])
    assert {"Hips", "Spine", "Neck", "Head", "LowerBack"} <= central
    assert names[perm][list(names).index("LeftFoot")] == "RightFoot"


def test_mirroring_twice_gives_the_motion_back(avatar):
    motion = load_motion("spin", avatar).slice(0, 20)
    back = mirror_motion(mirror_motion(motion))
    np.testing.assert_allclose(back.rotations, motion.rotations, atol=1e-6)
    np.testing.assert_array_equal(back.root_translation, motion.root_translation)
    assert not back.meta.get("mirrored") and mirror_motion(motion).meta["mirrored"]


def test_the_mirrored_body_is_the_body_mirrored(avatar):
    motion = load_motion("spin", avatar).slice(20, 26)  # mid-turn: far from symmetric
    perm = mirror_permutation(avatar.joint_names)
    heads = avatar.pose_motion(motion).joint_poses[..., :3, 3].numpy()  # (T, J, 3)
    mirrored = avatar.pose_motion(mirror_motion(motion)).joint_poses[..., :3, 3].numpy()
    expected = heads[:, perm] @ REFLECT
    assert np.abs(expected - heads).max() > 0.1  # the pose is not symmetric itself
    # anny's skeleton is symmetric to within millimetres
    np.testing.assert_allclose(mirrored, expected, atol=5e-3)
    body = avatar.pose_motion(mirror_motion(motion)).vertices.numpy()
    original = avatar.pose_motion(motion).vertices.numpy() @ REFLECT
    # the same body surface, mirrored (vertex order aside): centroids and extents agree
    np.testing.assert_allclose(body.mean(1), original.mean(1), atol=5e-3)
    np.testing.assert_allclose(
        body.max(1) - body.min(1), original.max(1) - original.min(1), atol=1e-2
    )


def test_mirror_spec_and_a_skeleton_without_twins(avatar):
    a = load_motion("mirror:spin", avatar, max_frames=10)
    b = mirror_motion(load_motion("spin", avatar, max_frames=10))
    np.testing.assert_array_equal(a.rotations, b.rotations)
    assert a.name.startswith("mirror:")
    names = ("Hips", "LeftUpLeg")
    lone = Motion(names, np.tile(np.eye(3), (2, 2, 1, 1)), np.zeros((2, 3)), 30.0)
    with pytest.raises(LoosefitInputError, match="RightUpLeg"):
        mirror_motion(lone)


def test_garment_twins_and_mirroring(skirt):
    twins = vertex_twins(skirt.vertices)
    assert (twins[twins] == np.arange(skirt.num_vertices)).all()
    frames = np.random.default_rng(0).normal(size=(3, skirt.num_vertices, 3)).astype(np.float32)
    np.testing.assert_allclose(mirror_garment(mirror_garment(frames, twins), twins), frames)
    np.testing.assert_allclose(mirror_garment(skirt.vertices, twins), skirt.vertices, atol=1e-3)
    lopsided = skirt.vertices.copy()
    lopsided[0, 0] += 0.01
    with pytest.raises(LoosefitInputError, match="symmetric about X = 0"):
        vertex_twins(lopsided)
