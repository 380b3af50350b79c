"""The pose check on imported motions (pose_check.py): what dancers do passes, what no
body can do is refused naming the frames and the joints."""

import dataclasses

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from loosefit.errors import LoosefitInputError
from loosefit.motion.motions import PROCEDURAL_NAMES, load_motion
from loosefit.motion.pose_check import MAX_TURN_DEG_S, check_pose, measure_pose, pose_problems
from loosefit.motion.retarget import RetargetConfig
from loosefit.types import Motion
from tests.conftest import SALSA
from tests.motion.bvh_conventions import CONVENTIONS, STUDIO_X, write_convention_bvh

BALLET = SALSA.parent / "cmu-ballet"


def _check(avatar, motion):
    return check_pose(motion, avatar.skeleton, avatar.floor_height)


@pytest.mark.parametrize("spec", [*PROCEDURAL_NAMES, "dance:20"])
def test_every_procedural_motion_passes(avatar, spec):
    motion = load_motion(spec, avatar, seed=1)
    m = _check(avatar, motion)
    assert m.upright.all() and m.turn.max() < MAX_TURN_DEG_S / 5


@pytest.mark.parametrize(
    "clip",
    [
        "cmu-salsa/60_01",
        "cmu-salsa/60_04",
        "cmu-ballet/05_06",
        "cmu-ballet/05_16",
        "cmu-ballet/05_05",
    ],
)
def test_the_hardest_cmu_clips_pass(avatar, clip):
    # 60_01: feet flipped for 100 frames; 60_04: a hip jump; 05_06: a cartwheel (the fewest
    # frames upright); 05_16: a thigh flipping over four frames (the fastest bone); 05_05:
    # leaps (the fewest frames on the floor). bench/data/pose_check_margins.py runs all 31.
    path = SALSA.parent / f"{clip}.bvh"
    if not path.is_file():
        pytest.skip(f"{path} is not present beside the repository")
    load_motion(str(path), avatar)  # refused here if it failed


def test_a_body_lying_down_is_refused_naming_frames_and_joints(avatar):
    motion = load_motion("sway", avatar)
    turn = Rotation.from_euler("x", 90, degrees=True).as_matrix().astype(np.float32)
    rot = motion.rotations.copy()
    rot[:, 0] = turn @ rot[:, 0]  # the whole body tipped onto its back
    lying = dataclasses.replace(motion, rotations=rot)
    with pytest.raises(LoosefitInputError) as err:
        check_pose(lying, avatar.skeleton, avatar.floor_height, "lying.bvh")
    text = str(err.value)
    assert text.startswith("lying.bvh: field 'poses'") and "does not stand in 100%" in text
    assert f"Head not above Hips in frames 0-{motion.num_frames - 1}" in text
    assert "--sheet" in text and "--no-pose-check" in text


def test_feet_off_the_floor_or_through_it_are_refused(avatar):
    motion = load_motion("walk", avatar)
    up = dataclasses.replace(motion, root_translation=motion.root_translation + [0, 0, 0.6])
    problems = pose_problems(
        measure_pose(up, avatar.skeleton, avatar.floor_height), avatar.skeleton.names
    )
    assert len(problems) == 1 and "the feet meet the floor (within 10 cm) in 0%" in problems[0]
    down = dataclasses.replace(motion, root_translation=motion.root_translation - [0, 0, 0.4])
    with pytest.raises(LoosefitInputError, match=r"a foot is 0\.4\d m below the floor"):
        _check(avatar, down)


def test_a_joint_that_flips_in_one_frame_is_refused_at_the_clips_rate(avatar, tmp_path):
    motion = load_motion("sway", avatar, fps=120.0)
    j = avatar.joint_names.index("LeftForeArm")
    rot = motion.rotations.copy()
    flip = Rotation.from_euler("z", 150, degrees=True).as_matrix().astype(np.float32)
    rot[200:260, j] = flip @ rot[200:260, j]  # the forearm turns 150 degrees in 1/120 s
    # (its bone, not square to the turn's axis, swings 111 degrees)
    flipped = Motion(motion.joint_names, rot, motion.root_translation, motion.fps, "flip")
    with pytest.raises(LoosefitInputError) as err:
        _check(avatar, flipped)
    text = str(err.value)
    assert (
        "LeftForeArm 111 degrees at frame 199" in text
        and "75 degrees in one frame at 120 fps" in text
    )
    assert "frames 199, 259 (2 frames)" in text
    # Read from a file, the same: refused where it is read, at the file's rate; let
    # through on request.
    path = write_convention_bvh(
        tmp_path / "flip.bvh", CONVENTIONS["mixamo"], avatar.skeleton, flipped, avatar.floor_height
    )
    with pytest.raises(LoosefitInputError, match=r"flip\.bvh.*LeftForeArm 111 degrees"):
        load_motion(str(path), avatar)
    loose = RetargetConfig(check_pose=False)
    assert load_motion(str(path), avatar, retarget=loose).num_frames == motion.num_frames // 4


def test_the_studio_rig_passes_and_its_report_says_how_it_was_read(avatar, tmp_path):
    from loosefit.motion.inspect import inspect_motion

    motion = load_motion("dance:2", avatar, seed=5)
    path = write_convention_bvh(
        tmp_path / "studio.bvh", STUDIO_X, avatar.skeleton, motion, avatar.floor_height
    )
    load_motion(str(path), avatar)
    text = inspect_motion(path).format()
    for part in (
        "axes: up +y (found from the frames (feet to head)), forward +z",
        "calibration: clip",
        "the zero pose does not stand",
        "matched on frame 0: the zero pose shows no legs below the pelvis",
        "above the ankles at frame",
    ):
        assert part in text, part
    assert "rest skeleton's extent" not in text
