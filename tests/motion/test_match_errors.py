"""The joint matcher's error: what nothing drives, the joints named like it, a map's lines."""

import pickle

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.motion.joint_names import REQUIRED, classify_joint_name
from loosefit.motion.match_errors import SkeletonMatchError, map_file_hint, raise_no_match

# A skeleton with its right leg and arm gone: a pelvis, a spine, a left leg and arm.
NAMES = ["Hips", "Spine", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftArm", "LeftForeArm", "Hand_L"]
PARENTS = np.array([-1, 0, 0, 2, 3, 1, 5, 6])
FOUND = {"Hips": 0, "LeftUpLeg": 2, "LeftLeg": 3, "LeftFoot": 4, "LeftArm": 5}


def _raised(**kw) -> SkeletonMatchError:
    parts = [classify_joint_name(n) for n in NAMES]
    with pytest.raises(SkeletonMatchError) as err:
        raise_no_match("half.bvh", NAMES, parts, FOUND, ["the pelvis: Hips"], **kw)
    return err.value


def test_the_error_names_what_nothing_drives_and_the_joints_named_like_it():
    missing = ["LeftForeArm", "LeftHand", "RightUpLeg"]
    exc = _raised(missing=missing, parents=PARENTS)
    assert isinstance(exc, LoosefitInputError) and exc.missing == tuple(missing)
    assert exc.details == (
        "LeftForeArm: candidates ['LeftForeArm']",
        "LeftHand: candidates ['Hand_L']",
        "RightUpLeg: no joint named like UpLeg, Thigh, UpperLeg, Hip",
    )
    # the names guess the left forearm and hand (not taken), nothing for the right thigh
    assert exc.guesses == {"LeftForeArm": "LeftForeArm", "LeftHand": "Hand_L"}
    assert exc.notes == ("the pelvis: Hips",)
    text = str(exc)
    assert "half.bvh" in text and "HIERARCHY" in text and "the pelvis: Hips" in text
    assert "'LeftHand: Hand_L'" in text and "--joint-map" in text


def test_without_a_list_every_required_joint_is_missing_and_without_parents_no_guess():
    exc = _raised()
    assert exc.missing == REQUIRED and exc.guesses == {}


def test_the_error_survives_pickling_with_its_fields():
    exc = _raised(missing=["RightHand"], parents=PARENTS)
    back = pickle.loads(pickle.dumps(exc))
    assert type(back) is SkeletonMatchError and str(back) == str(exc)
    for name in ("missing", "notes", "guesses", "details"):
        assert getattr(back, name) == getattr(exc, name), name


def test_the_hint_lists_the_guessed_lines_or_an_example():
    assert "'LeftHand: Hand_L'" in map_file_hint("a.bvh", {"LeftHand": "Hand_L"})
    plain = map_file_hint("a.bvh")
    assert "e.g." in plain and "inspect-motion a.bvh --write-joint-map" in plain
