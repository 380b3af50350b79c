import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.motion.joint_map_files import check_joint_map, joint_map_template
from loosefit.motion.joint_maps import JointMap, load_joint_map_file
from loosefit.motion.joint_match import JointMatch

# a small skeleton: pelvis, a spine, a left leg and a left arm with an elbow in it
NAMES = "root pelvis spine chest thigh_l knee_l foot_l upper_l elbow_l hand_l".split()
PARENTS = np.array([-1, 0, 1, 2, 1, 4, 5, 3, 7, 8])
GOOD = {
    "Hips": "pelvis",
    "Spine1": "chest",
    "LeftUpLeg": "thigh_l",
    "LeftLeg": "knee_l",
    "LeftFoot": "foot_l",
    "LeftArm": "upper_l",
    "LeftForeArm": "elbow_l",
    "LeftHand": "hand_l",
}


def _positions(elbow_bend_deg: float) -> np.ndarray:
    """(2, J, 3) joints at rest and with the elbow bent by ``elbow_bend_deg``."""
    x = [0, 0, 0, 0, 0.1, 0.1, 0.1, 0.2, 0.5, 0.8]
    z = [1.0, 1.0, 1.2, 1.4, 0.95, 0.5, 0.1, 1.4, 1.4, 1.4]
    p = np.stack([x, np.zeros(10), z], axis=1)
    bent = p.copy()
    a = np.radians(elbow_bend_deg)
    bent[9] = bent[8] + 0.3 * np.array([np.cos(a), 0.0, np.sin(a)])
    return np.stack([p, bent])


def test_a_template_of_guesses_reads_back_as_a_map(tmp_path):
    text = joint_map_template(NAMES, None, "/data/walk.bvh", axes=("+z", "-y"), parents=PARENTS)
    assert text.startswith("# Joint map for walk.bvh:")
    assert f"# The file's joints: {', '.join(NAMES)}" in text
    assert "# RightUpLeg: ?   # thigh" in text  # nothing on the right: a line to fill in
    path = tmp_path / "map.yaml"
    path.write_text(text)
    jmap = load_joint_map_file(path, NAMES)
    assert jmap.joints["Hips"] == "pelvis" and jmap.joints["LeftUpLeg"] == "thigh_l"
    assert (jmap.source_up, jmap.source_forward) == ("+z", "-y")


def test_a_template_writes_the_matchers_map_and_quotes_awkward_names(tmp_path):
    joints = {"Hips": "yes", "LeftUpLeg": "leg:L", "Head": "head"}
    match = JointMatch(JointMap("auto-matched", joints), {"Hips": "structure", "Head": "name"})
    text = joint_map_template(["yes", "leg:L", "head"], match, "clip.bvh")
    assert "Hips: 'yes'  # structure" in text
    assert "LeftUpLeg: 'leg:L'\n" in text and "Head: head  # name" in text
    assert "source_up" not in text
    path = tmp_path / "map.yaml"
    path.write_text(text)
    assert load_joint_map_file(path).joints == joints


def test_joints_out_of_their_chains_order_are_refused():
    check_joint_map(GOOD, NAMES, PARENTS, _positions(0.0), "/x/walk.bvh", "map.yaml")
    swapped = GOOD | {"LeftLeg": "foot_l", "LeftFoot": "knee_l"}
    with pytest.raises(LoosefitInputError) as err:
        check_joint_map(swapped, NAMES, PARENTS, _positions(0.0), "/x/walk.bvh", "map.yaml")
    assert (err.value.source, err.value.field) == ("map.yaml", "LeftFoot")
    assert "'knee_l', which is not below LeftLeg 'foot_l'" in err.value.found
    assert err.value.expected == "a joint map that fits walk.bvh's skeleton"


def test_a_pelvis_that_is_an_empty_root_is_refused():
    with pytest.raises(LoosefitInputError) as err:
        check_joint_map(GOOD | {"Hips": "root"}, NAMES, PARENTS, _positions(0), "w.bvh", "m")
    assert err.value.field == "Hips" and "one child 'pelvis'" in err.value.found


def test_a_bending_joint_left_out_of_a_limb_is_refused():
    skipped = GOOD | {"LeftForeArm": "hand_l"}  # over the elbow
    skipped.pop("LeftHand")
    check_joint_map(skipped, NAMES, PARENTS, _positions(15.0), "w.bvh", "m")  # nearly straight
    with pytest.raises(LoosefitInputError) as err:
        check_joint_map(skipped, NAMES, PARENTS, _positions(60.0), "w.bvh", "m")
    assert err.value.field == "LeftArm"
    assert "passing over 'elbow_l'" in err.value.found and "60 degrees" in err.value.found
