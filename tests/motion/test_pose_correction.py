"""Capture poses that fold into the body, turned out of it (loosefit.motion.pose_correction)."""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.body.regions import body_parts
from loosefit.errors import LoosefitInputError
from loosefit.geometry.rotations import axis_angle_to_matrix, rotation_angle
from loosefit.motion.pose_correction import (
    LimbTest,
    UnfoldConfig,
    ease,
    fastest_axis,
    motion_cap,
    same_correction,
    unfold_motion,
    world_rotations,
)
from loosefit.types import Motion


@pytest.fixture(scope="module")
def parts(avatar):
    return body_parts(avatar, arms=False)  # a skirt's collider: the legs collide


def knee_lift(avatar, degrees: float, frames: int = 30, still: int = 0) -> Motion:
    """The left thigh raised from the rest pose to ``degrees`` of flexion and back down,
    ``still`` frames at rest before and after."""
    half = frames // 2
    up, down = np.linspace(0, degrees, half), np.linspace(degrees, 0, half)
    flex = np.radians(np.concatenate([np.zeros(still), up, down, np.zeros(still)]))
    m = avatar.rest_motion(len(flex))
    rot = m.rotations.copy()
    rot[:, avatar.joint_names.index("LeftUpLeg")] = axis_angle_to_matrix(
        np.stack([-flex, 0 * flex, 0 * flex], 1)  # about +x, backwards: the knee comes up
    )
    return Motion(m.joint_names, rot, m.root_translation, 30.0, "knee-lift")


def test_ease_never_falls_below_what_a_frame_needs_and_ramps_in_and_out():
    angle = np.zeros(40)
    angle[15:20] = [2.0, 5.0, 10.0, 7.0, 1.0]
    eased = ease(angle, 6)
    assert (eased >= angle - 1e-12).all()
    # the running maximum reaches 6 frames out, its smoothing 6 more: nothing beyond
    assert eased[:3].max() == 0.0 and eased[32:].max() == 0.0 and min(eased[3], eased[31]) > 0
    assert np.abs(np.diff(eased)).max() < 10.0 / 3  # eased in, not a jump of 10
    np.testing.assert_array_equal(ease(angle, 0), angle)


def test_the_fastest_axis_lifts_the_buried_points():
    class Hit:  # the plane z = 0, outside up
        def __init__(self, p):
            self.points = p * np.array([1.0, 1.0, 0.0])
            self.inside = p[:, 2] < 0

    class Plane(LimbTest):
        def __init__(self):
            self.tested = np.arange(3)

        def signed(self, body):
            return body[:, 2].copy(), Hit(body)

    body = np.array([[1.0, 0.0, -0.02], [1.2, 0.0, -0.01], [0.5, 0.0, 0.3]])
    axis = fastest_axis(Plane(), body, np.zeros(3), clearance=0.01)
    np.testing.assert_allclose(axis, [0.0, -1.0, 0.0], atol=1e-9)  # +x lifted by a turn about -y
    turned = body @ axis_angle_to_matrix(axis * 0.05).astype(np.float64).T
    assert (turned[:2, 2] > body[:2, 2]).all()


def test_world_rotations_compose_down_the_chain():
    R = axis_angle_to_matrix(np.random.default_rng(0).normal(size=(2, 3, 3))).astype(np.float64)
    G = world_rotations(R, [-1, 0, 1])
    np.testing.assert_allclose(G[:, 2], R[:, 0] @ R[:, 1] @ R[:, 2], atol=1e-12)


def test_a_motion_that_never_folds_is_returned_as_it_is(avatar, parts):
    motion = knee_lift(avatar, 45.0, frames=10)
    done = unfold_motion(avatar, motion, parts)
    assert done.motion is motion and done.frames == 0
    assert done.stats() == {
        "unfold_frames": 0,
        "unfold_degrees_max": 0.0,
        "fold_depth_before": 0.0,
        "fold_depth_after": 0.0,
    }


def test_a_thigh_raised_into_the_belly_is_turned_out_at_most_the_cap(avatar, parts):
    motion = knee_lift(avatar, 140.0, still=15)
    done = unfold_motion(avatar, motion, parts, UnfoldConfig(max_degrees=10.0))
    folded = done.depth_before > 0
    assert done.motion.num_frames == motion.num_frames  # a data set's frame counts stay
    assert done.depth_before.max() > 0.05 and folded.sum() >= 8  # 6.7 cm at the top
    assert (done.depth_after <= done.depth_before + 1e-9).all()
    assert done.depth_after.max() < done.depth_before.max() - 0.01  # 10 degrees: 1.7 cm less
    assert done.degrees.max() == pytest.approx(10.0) and (done.degrees <= 10.0 + 1e-9).all()
    # only the left hip turned, by what the record says, and only near the folded frames
    j = avatar.joint_names.index("LeftUpLeg")
    changed = np.abs(done.motion.rotations - motion.rotations).max((2, 3))  # (T, J)
    assert set(np.flatnonzero(changed.max(0) > 0)) == {j}
    turned = np.degrees(rotation_angle(done.motion.rotations[:, j], motion.rotations[:, j]))
    np.testing.assert_allclose(turned, done.degrees, atol=1e-3)
    span = np.flatnonzero(folded)
    radius = round(0.2 * motion.fps) * 2  # the ramp's running maximum and smoothing
    outside = np.ones(len(folded), bool)
    outside[max(span[0] - radius, 0) : span[-1] + radius + 1] = False
    assert not done.degrees[outside].any() and outside.any()
    np.testing.assert_array_equal(done.motion.root_translation, motion.root_translation)


def test_a_shallow_fold_is_cleared_with_room_to_spare(avatar, parts):
    motion = knee_lift(avatar, 100.0)
    done = unfold_motion(avatar, motion, parts, UnfoldConfig(max_degrees=60.0, clearance=0.005))
    assert done.depth_before.max() > 0.01 and done.depth_after.max() == 0.0
    assert 0 < done.degrees.max() < 60.0  # the smallest turn, not the cap


def test_a_motion_with_a_deep_leg_fold_gets_the_deep_cap_for_every_limb():
    config = UnfoldConfig(max_degrees=10.0, deep_degrees=30.0, deep_depth=0.05)
    assert motion_cap(config, {"left leg": 0.06, "right arm": 0.0}) == 30.0
    assert motion_cap(config, {"left leg": 0.05, "right arm": 0.09}) == 10.0  # arms don't count
    assert motion_cap(UnfoldConfig(), {"left leg": 0.09}) == 10.0  # deep_degrees None


def test_a_deep_fold_is_turned_as_the_deep_cap_would_turn_it(avatar, parts):
    motion = knee_lift(avatar, 140.0, still=15)  # 6.7 cm into the belly at the top
    flat = unfold_motion(avatar, motion, parts, UnfoldConfig(max_degrees=10.0))
    deep = unfold_motion(avatar, motion, parts, UnfoldConfig(max_degrees=10.0, deep_degrees=30.0))
    assert 10.0 + 1 < deep.degrees.max() <= 30.0 + 1e-6
    assert deep.depth_after.max() < flat.depth_after.max() - 0.01
    np.testing.assert_array_equal(deep.depth_before, flat.depth_before)
    thirty = unfold_motion(avatar, motion, parts, UnfoldConfig(max_degrees=30.0))
    np.testing.assert_array_equal(deep.motion.rotations, thirty.motion.rotations)


def test_same_correction_tells_whether_two_caps_change_a_motion(avatar, parts):
    base, deep = UnfoldConfig(), UnfoldConfig(deep_degrees=30.0)
    shallow = knee_lift(avatar, 100.0)
    assert 0.01 < unfold_motion(avatar, shallow, parts).depth_before.max() < 0.05
    assert same_correction(avatar, shallow, parts, base, deep)  # no fold reaches 5 cm
    np.testing.assert_array_equal(
        unfold_motion(avatar, shallow, parts, base).motion.rotations,
        unfold_motion(avatar, shallow, parts, deep).motion.rotations,
    )
    assert not same_correction(avatar, shallow, parts, base, UnfoldConfig(max_degrees=20.0))
    assert not same_correction(avatar, shallow, parts, base, UnfoldConfig(clearance=0.02))
    assert not same_correction(avatar, knee_lift(avatar, 140.0), parts, base, deep)  # 6.7 cm
    never = knee_lift(avatar, 45.0, frames=10)
    assert same_correction(avatar, never, parts, base, UnfoldConfig(max_degrees=20.0))
    off = UnfoldConfig(enabled=False)
    assert same_correction(avatar, shallow, parts, off, UnfoldConfig(enabled=False, steps=3))


def test_the_configuration_is_checked():
    for bad in (
        {"max_degrees": -1.0},
        {"max_degrees": 120.0},
        {"clearance": float("nan")},
        {"steps": 0},
        {"enabled": "yes"},
        {"ramp_seconds": True},
        {"deep_degrees": 5.0},
        {"deep_degrees": 95.0},
        {"deep_degrees": float("inf")},
        {"deep_depth": -0.01},
        {"deep_depth": float("nan")},
        {"deep_limbs": ("tail",)},
    ):
        with pytest.raises(LoosefitInputError, match="UnfoldConfig"):
            UnfoldConfig(**bad)


def test_ease_holds_a_value_up_to_the_ends():
    np.testing.assert_allclose(ease(np.full(5, 3.0), 6), 3.0)


def test_a_limb_test_answers_the_same_from_where_it_last_looked(avatar, parts):
    """Each query starts from the faces the last one found: the same distances and sides as
    a query from nothing, pose after pose."""
    from loosefit.motion.pose_correction import LimbTest

    rest = avatar.rest_vertices.double().numpy()
    test = LimbTest(parts, "left leg", rest)
    motion = knee_lift(avatar, 140.0)
    body = avatar.pose_motion(motion).vertices.double().numpy()
    for frame in body[::3]:
        hinted, _ = test.signed(frame)
        test._hint = None
        fresh, _ = test.signed(frame)
        np.testing.assert_array_equal(hinted, fresh)
