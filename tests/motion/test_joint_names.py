"""What joint names say: side and part, and the avatar joint a name suggests."""

import numpy as np
import pytest

from loosefit.motion.joint_names import classify_joint_name, guess_by_name


@pytest.mark.parametrize(
    "name, side, part",
    [
        ("mixamorig:LeftUpLeg", "L", "thigh"),
        ("mixamorig:RightToeBase", "R", "toe"),
        ("mixamorig:Spine2", None, "spine"),
        ("mixamorig:LeftHandIndex1", "L", None),  # a finger
        ("mixamorig:HeadTop_End", None, None),
        ("thigh_l", "L", "thigh"),
        ("calf_r", "R", "shin"),
        ("ball_l", "L", "toe"),
        ("clavicle_l", "L", "collar"),
        ("lowerarm_r", "R", "forearm"),
        ("spine_03", None, "spine"),
        ("neck_01", None, "neck"),
        ("left_hip", "L", "hip"),
        ("left_ankle", "L", "foot"),
        ("right_wrist", "R", "hand"),
        ("left_shoulder", "L", "shoulder"),
        ("UpperLeg_L", "L", "thigh"),
        ("LowerLeg_R", "R", "shin"),
        ("Toes_L", "L", "toe"),
        ("joint_Root", None, "root"),
        ("lThigh", "L", "thigh"),
        ("rShldr", "R", "upperarm"),
        ("lButtock", "L", "hipjoint"),
        ("LHipJoint", "L", "hipjoint"),
        ("hip", None, "root"),
        ("abdomen", None, "spine"),
        ("LowerBack", None, "spine"),
        ("Bip01 L Calf", "L", "shin"),
        ("Arm.L", "L", "upperarm"),
        ("hand.R", "R", "hand"),
        ("Left_Elbow", "L", "forearm"),
        ("LeftLeg", "L", "shin"),
        ("Leg_R", "R", "shin"),
        ("Root", None, "root"),
    ],
)
def test_joint_names_give_side_and_part(name, side, part):
    got = classify_joint_name(name)
    assert (got.side, got.part) == (side, part), got


def test_the_names_guess_a_pelvis_that_branches_and_tell_a_collar_from_an_upper_arm():
    # No joint named as a pelvis branches: the first that does, said so; an empty root
    # named so is never taken, and the line says why.
    names = ["joint_Root", "Body", "UpperLeg_L", "UpperLeg_R", "Spine"]
    parents = np.array([-1, 0, 1, 1, 1])
    assert guess_by_name(names, parents)["Hips"] == (
        "Body",
        "by structure: the first joint that branches",
    )
    out = guess_by_name(["Root", "Hips"], np.array([-1, 0]))
    assert out["Hips"][0] is None and "'Root' is named so but does not branch" in out["Hips"][1]
    # a sided Shoulder above an upper arm of its side is the collar; alone, the upper arm
    names = ["Hips", "Shoulder_L", "UpperArm_L", "Shoulder_R"]
    out = guess_by_name(names, np.array([-1, 0, 1, 0]))
    assert out["LeftShoulder"][0] == "Shoulder_L" and out["LeftArm"][0] == "UpperArm_L"
    assert out["RightArm"][0] == "Shoulder_R" and "RightShoulder" not in out
