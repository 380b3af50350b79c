"""What every kind of trained model shares: the runtime and motion checks, a checkpoint's
avatar and the arms its data's simulation had in the collider."""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.inference.model_common import (
    RUNTIMES,
    arm_collision_of,
    check_motion_joints,
    check_runtime,
)
from loosefit.types import Motion


def _motion(joints=("root", "hips")) -> Motion:
    T, J = 3, len(joints)
    rotations = np.tile(np.eye(3, dtype=np.float32), (T, J, 1, 1))
    return Motion(tuple(joints), rotations, np.zeros((T, 3), np.float32), 30.0, "m")


def test_the_runtimes_are_torch_and_onnx_and_another_is_refused_by_name():
    assert RUNTIMES == ("torch", "onnx")
    for runtime in RUNTIMES:
        check_runtime(runtime)
    with pytest.raises(LoosefitInputError, match=r"runtime.*'torch' or 'onnx'.*'tensorrt'"):
        check_runtime("tensorrt")


def test_a_motion_on_other_joints_or_not_finite_is_refused(tmp_path):
    check_motion_joints(_motion(), ("root", "hips"), tmp_path / "model.pt")
    with pytest.raises(LoosefitInputError, match=r"model\.pt.*missing \['knee'\]"):
        check_motion_joints(_motion(), ("root", "hips", "knee"), tmp_path / "model.pt")
    with pytest.raises(LoosefitInputError, match="in another order"):
        check_motion_joints(_motion(("hips", "root")), ("root", "hips"), tmp_path / "model.pt")
    broken = _motion()
    broken.root_translation[1, 2] = np.inf  # after its own checks, as a rollout could see it
    with pytest.raises(LoosefitInputError, match="NaN or infinity"):
        check_motion_joints(broken, ("root", "hips"), tmp_path / "model.pt")


@pytest.mark.parametrize(
    ("cloth", "default", "want"),
    [
        ({}, False, False),  # data from before the field: the default
        ({}, "upper", "upper"),
        ({"arm_collision": True}, False, True),
        ({"arm_collision": "upper"}, False, "upper"),
        ({"arm_collision": 0}, True, False),
        ({"arm_collision": False, "arm_friction": 0.3}, False, True),  # a collider of their own
    ],
)
def test_the_arms_in_the_collider_are_the_data_s(cloth, default, want):
    assert arm_collision_of({"cloth": cloth}, default) == want
