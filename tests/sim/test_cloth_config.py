"""The physics' configuration (loosefit.sim.cloth_config): its checks."""

from __future__ import annotations

import pytest

from loosefit.errors import LoosefitInputError
from loosefit.sim.cloth_config import ClothConfig


def test_arm_friction_is_checked():
    assert ClothConfig().colliding_arms is True  # the arms as a mesh of their own
    assert ClothConfig(arm_friction=None).colliding_arms is False
    with pytest.raises(LoosefitInputError, match="arm_friction"):
        ClothConfig(arm_friction=-0.1)
    with pytest.raises(LoosefitInputError, match="arm_friction"):
        ClothConfig(arm_friction=float("nan"))
    assert ClothConfig(arm_collision="upper", arm_friction=0.0).arm_friction == 0.0


def test_release_depth_is_checked():
    with pytest.raises(LoosefitInputError, match="release_depth"):
        ClothConfig(release_depth=-0.01)
    assert ClothConfig(release_depth=0.02).release_depth == 0.02
