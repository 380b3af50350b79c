"""A clip's kinematics against hand-computed answers: world transforms, rest pose, the body."""

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from loosefit.errors import LoosefitInputError
from loosefit.motion.skeleton_clip import (
    BvhClip,
    body_extent,
    body_joints,
    end_site_positions,
    forward_kinematics,
    forward_kinematics_arrays,
    rest_positions,
)


def _loop_fk(parents, rotations, translations):
    """Plain per-frame, per-joint 4x4 products: G_j = G_parent @ [R_j | t_j]."""
    T, J = rotations.shape[:2]
    pos, rot = np.zeros((T, J, 3)), np.zeros((T, J, 3, 3))
    for t in range(T):
        world = []
        for j in range(J):
            local = np.eye(4)
            local[:3, :3], local[:3, 3] = rotations[t, j], translations[t, j]
            world.append(local if parents[j] < 0 else world[parents[j]] @ local)
            pos[t, j], rot[t, j] = world[j][:3, 3], world[j][:3, :3]
    return pos, rot


def test_forward_kinematics_matches_the_product_of_4x4_transforms():
    parents = np.array([-1, 0, 1, 1, 3])
    rng = np.random.default_rng(0)
    rotations = Rotation.random(3 * 5, random_state=1).as_matrix().reshape(3, 5, 3, 3)
    translations = rng.normal(size=(3, 5, 3))
    pos, rot = forward_kinematics_arrays(parents, rotations, translations)
    want_pos, want_rot = _loop_fk(parents, rotations, translations)
    assert pos.dtype == np.float32 and pos.shape == (3, 5, 3) and rot.shape == (3, 5, 3, 3)
    np.testing.assert_allclose(pos, want_pos, atol=1e-5)
    np.testing.assert_allclose(rot, want_rot, atol=1e-6)
    # (J, 3) offsets broadcast over the frames as a (T, J, 3) array does
    same, _ = forward_kinematics_arrays(parents, rotations, translations[0])
    np.testing.assert_allclose(
        same, _loop_fk(parents, rotations, translations[[0, 0, 0]])[0], atol=1e-5
    )


def _chain_clip() -> BvhClip:
    """root -> a (1 m up) -> b (1 m up), b's End Site 0.5 m along its X; frame 1 turns a
    by 90 degrees about Z."""
    turn = Rotation.from_euler("z", 90, degrees=True).as_matrix()
    rotations = np.tile(np.eye(3, dtype=np.float32), (2, 3, 1, 1))
    rotations[1, 1] = turn
    offsets = np.array([[0, 0, 0], [0, 1, 0], [0, 1, 0]], np.float32)
    return BvhClip(
        path=Path("chain.bvh"),
        joint_names=("root", "a", "b"),
        parents=np.array([-1, 0, 1]),
        offsets=offsets,
        channels=[("Zrotation",)] * 3,
        end_offsets={2: np.array([0.5, 0, 0], np.float32)},
        rotations=rotations,
        local_translations=np.tile(offsets, (2, 1, 1)),
        frame_time=0.04,
    )


def test_a_turned_joint_moves_its_children_and_end_site():
    clip = _chain_clip()
    pos, _ = forward_kinematics(clip)
    np.testing.assert_allclose(pos[0], [[0, 0, 0], [0, 1, 0], [0, 2, 0]], atol=1e-6)
    np.testing.assert_allclose(pos[1], [[0, 0, 0], [0, 1, 0], [-1, 1, 0]], atol=1e-6)
    ends = end_site_positions(clip)
    np.testing.assert_allclose(ends[2], [[0.5, 2, 0], [-1, 1.5, 0]], atol=1e-6)
    np.testing.assert_allclose(rest_positions(clip), pos[0], atol=1e-6)
    assert clip.fps == pytest.approx(25.0) and clip.num_frames == 2 and clip.num_joints == 3
    assert clip.index("b") == 2
    with pytest.raises(LoosefitInputError, match="chain.bvh.*joint name"):
        clip.index("c")


def test_the_body_starts_at_the_first_joint_that_branches():
    # an empty root and a joint on its way down, then hips with two legs and a spine
    parents = np.array([-1, 0, 1, 2, 2, 2, 3])
    assert body_joints(parents) == [2, 3, 4, 5, 6]
    assert body_joints(np.array([-1, 0, 1])) == [0, 1, 2]  # a chain: all of it
    offsets = np.array(
        [[0, 0, 0], [5, 0, 0], [0, 0, 0], [0, -1, 0], [1, 0, 0], [0, 2, 0], [0, -1, 0]], float
    )
    # the body spans y from -2 (the knee below a leg) to +2.5 (the spine's End Site), not
    # the root's 5 m to the side
    assert body_extent(parents, offsets, {5: np.array([0, 0.5, 0])}) == pytest.approx(4.5)
