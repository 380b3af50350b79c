import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.motion.procedural import MOVES, MoveSpec, compose, named_motion, random_dance


def _heading(motion):
    R = motion.rotations[:, 0]
    fwd = R @ np.array([0.0, -1.0, 0.0])
    return np.unwrap(np.arctan2(fwd[:, 0], -fwd[:, 1]))


@pytest.mark.parametrize("name", list(MOVES))
def test_every_move_poses_the_body_on_the_floor(avatar, name):
    motion = named_motion(name, avatar.joint_names, avatar.floor_height, seed=1)
    body = avatar.pose_motion(motion)
    lowest = body.vertices[:, :, 2].min(1).values.numpy()
    assert lowest.min() > -0.1, f"{name} sinks {lowest.min():.3f} m into the floor"
    if name != "jump":
        assert np.median(lowest) < 0.06, f"{name} floats {np.median(lowest):.3f} m above the floor"
    # Smooth: no joint jumps more than 40 degrees between frames at 30 fps.
    R = motion.rotations
    rel = np.einsum("tjab,tjac->tjbc", R[:-1], R[1:])
    angle = np.degrees(np.arccos(np.clip((np.trace(rel, axis1=-2, axis2=-1) - 1) / 2, -1, 1)))
    assert angle.max() < 40, f"{name}: {angle.max():.1f} deg in one frame"


def test_spin_is_fast_enough_to_flare_a_skirt(avatar):
    motion = named_motion("spin", avatar.joint_names, avatar.floor_height, seed=3)
    rate = np.abs(np.diff(_heading(motion))) * motion.fps
    assert rate.max() > 2 * np.pi * 1.0  # at least a turn a second
    assert np.abs(motion.root_translation[:, :2]).max() < 0.05  # on the spot


def test_a_bow_folds_the_torso_forward_with_the_legs_upright(avatar):
    names = list(avatar.joint_names)
    pitch = {}
    for depth in (1.13, 1.48):  # the range a bow's depth is drawn from
        motion = compose(
            [MoveSpec("idle", 0.5), MoveSpec("bow", 3.0, {"depth": depth})],
            avatar.joint_names,
            avatar.floor_height,
        )
        joints = avatar.pose_motion(motion).joint_poses[:, :, :3, 3].numpy()
        torso = joints[:, names.index("Neck")] - joints[:, 0]
        angle = np.degrees(np.arccos(torso[:, 2] / np.linalg.norm(torso, axis=1)))
        t = int(np.argmax(angle))
        pitch[depth] = angle[t]
        assert torso[t, 1] < 0  # forward: the avatar faces -Y
        for side in ("Left", "Right"):  # the legs stay under the body, near vertical
            leg = joints[t, names.index(f"{side}Foot")] - joints[t, names.index(f"{side}UpLeg")]
            assert np.degrees(np.arccos(-leg[2] / np.linalg.norm(leg))) < 20
    assert 55 < pitch[1.13] < 62 and 72 < pitch[1.48] < 80  # the docstring's 57-76 degrees


def test_walk_moves_forward(avatar):
    motion = named_motion("walk", avatar.joint_names, avatar.floor_height, seed=0)
    # Facing -Y: walking goes towards -Y.
    assert motion.root_translation[-1, 1] < -1.0


def test_jump_leaves_the_ground(avatar):
    motion = named_motion("jump", avatar.joint_names, avatar.floor_height, seed=0)
    body = avatar.pose_motion(motion)
    assert float(body.vertices[:, :, 2].min(1).values.max()) > 0.08


def test_random_dance_is_deterministic_and_varied(avatar):
    a = random_dance(avatar.joint_names, avatar.floor_height, 10.0, seed=5)
    b = random_dance(avatar.joint_names, avatar.floor_height, 10.0, seed=5)
    c = random_dance(avatar.joint_names, avatar.floor_height, 10.0, seed=6)
    assert np.array_equal(a.rotations, b.rotations)
    assert not np.array_equal(a.rotations[: c.num_frames], c.rotations[: a.num_frames])
    assert 9.0 <= a.duration <= 12.5


def test_bad_moves_are_rejected(avatar):
    with pytest.raises(LoosefitInputError, match="moonwalk"):
        compose([MoveSpec("moonwalk", 1.0)], avatar.joint_names, avatar.floor_height)
    with pytest.raises(LoosefitInputError, match="duration"):
        compose([MoveSpec("walk", 0.0)], avatar.joint_names, avatar.floor_height)
    with pytest.raises(LoosefitInputError, match="LeftUpLeg"):
        compose([MoveSpec("walk", 1.0)], ("Hips",), 0.9)
