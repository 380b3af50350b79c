"""A clip's timeline (loosefit.sim.timeline): the preroll and the substeps of each frame."""

from __future__ import annotations

import math

import numpy as np

from loosefit.motion.chain import preroll
from loosefit.sim.timeline import body_moves, substep_schedule
from loosefit.types import Motion


def test_preroll_settles_at_the_start_then_blends_into_the_first_frame():
    T, J = 4, 3
    yaw = math.radians(90.0)
    rz = np.array(
        [[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0], [0, 0, 1]]
    )
    rot = np.tile(np.eye(3, dtype=np.float32), (T, J, 1, 1))
    rot[:, 0] = rz
    root = np.tile(np.array([2.0, 1.0, 0.95], np.float32), (T, 1))
    motion = Motion(("r", "a", "b"), rot, root, 30.0)
    r, t, n_settle = preroll(motion, 0.9, settle_seconds=0.5, blend_seconds=0.2)
    assert n_settle == 16 and r.shape == (16 + 6, J, 3, 3) and t.shape == (22, 3)
    np.testing.assert_allclose(r[0, 0], rz, atol=1e-6)  # turned to the motion's heading
    np.testing.assert_allclose(t[0], [2.0, 1.0, 0.9], atol=1e-6)  # on the floor where it starts
    np.testing.assert_allclose(np.diff(t[:n_settle], axis=0), 0.0)
    assert 0.9 < t[-1, 2] < 0.95 and np.all(np.diff(t[n_settle - 1 :, 2]) > 0)
    origin = preroll(motion, 0.9, 0.0, 0.2, settle_at_start=False)
    np.testing.assert_allclose(origin[0][0, 0], np.eye(3), atol=1e-6)
    np.testing.assert_allclose(origin[1][0], [0.0, 0.0, 0.9], atol=1e-6)
    assert origin[2] == 1


def test_substep_schedule_follows_the_fastest_waistband_point():
    T, W = 12, 4
    waist = np.zeros((T, W, 3))
    waist[7:, 2, 0] = 0.05  # one point jumps 5 cm between frames 6 and 7
    n = substep_schedule(waist, substeps=20, max_substeps=60, max_move=0.004, widen=2)
    assert n.shape == (T - 1,) and n.dtype == np.int64
    expected = np.full(T - 1, 20)
    # ceil(5 cm / 4 mm) = 13 < 20: the floor holds everywhere
    np.testing.assert_array_equal(n, expected)
    fast = substep_schedule(waist * 4, substeps=20, max_substeps=60, max_move=0.004, widen=2)
    expected[4:9] = 50  # 20 cm / 4 mm, on the jump and the two frames either side
    np.testing.assert_array_equal(fast, expected)
    capped = substep_schedule(waist * 10, substeps=20, max_substeps=60, max_move=0.004, widen=0)
    assert capped.max() == 60 and (capped == 60).sum() == 1


def test_body_moves_count_the_body_where_the_cloth_can_meet_it():
    T, Vb = 6, 3
    waist = np.zeros((T, 2, 3))
    waist[..., 2] = 1.0  # the waistband's top at 1 m
    body = np.zeros((T, Vb, 3))
    body[:, 0, 2] = 0.5  # a knee, below the waist
    body[:, 1, 2] = 1.5  # a shoulder, above it
    body[:, 2, 2] = 1.5  # a hand coming down to the skirt at frame 4
    body[4:, 2, 2] = 0.9
    body[3, 0, 0] = 0.03  # the knee kicks 3 cm out at frame 3 and back
    body[:, 1, 0] = np.arange(T) * 0.5  # the shoulder flies: it cannot touch the skirt
    moves = body_moves(body, waist)
    # the kick out (frame 2 to 3); the hand coming down to the skirt's height (3 to 4) and
    # the knee going back; never the shoulder
    np.testing.assert_allclose(moves, [0.0, 0.0, 0.03, 0.6, 0.0], atol=1e-9)


def test_substep_schedule_gives_a_fast_leg_its_substeps():
    T = 8
    waist = np.zeros((T, 3, 3))
    legs = np.zeros(T - 1)
    legs[3] = 0.2  # a kick: 20 cm in a frame
    slow = substep_schedule(waist, 10, 60, 0.004, widen=1)
    np.testing.assert_array_equal(slow, np.full(T - 1, 10))  # not counted without a limit
    n = substep_schedule(waist, 10, 60, 0.004, widen=1, body_moves=legs, max_body_move=0.01)
    np.testing.assert_array_equal(n, [10, 10, 20, 20, 20, 10, 10])
    # the larger demand of the waist and the legs
    waist[4:, 0, 0] = 0.12  # 12 cm: 30 substeps at 4 mm
    both = substep_schedule(waist, 10, 60, 0.004, widen=0, body_moves=legs, max_body_move=0.01)
    np.testing.assert_array_equal(both, [10, 10, 10, 30, 10, 10, 10])
