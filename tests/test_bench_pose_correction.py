"""The geometry of bench/pose_correction.py (issue 26's measured pose correction)."""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

import pose_correction as pc  # noqa: E402


def test_ease_covers_every_frame_and_ramps_in_and_out():
    angle = np.zeros(40)
    angle[15:20] = [2.0, 5.0, 10.0, 7.0, 1.0]
    eased = pc.ease(angle, 6)
    assert (eased >= angle - 1e-12).all()  # never less than a frame needs
    # the running maximum reaches 6 frames out, its smoothing 6 more: nothing beyond
    assert eased[:3].max() == 0.0 and eased[32:].max() == 0.0 and min(eased[3], eased[31]) > 0
    assert np.abs(np.diff(eased)).max() < 10.0 / 3  # eased in, not a jump of 10
    assert np.allclose(pc.ease(angle, 0), angle)


def test_fastest_axis_turns_buried_points_out():
    class Hit:  # a plane z = 0, outside up: points below it are inside
        def __init__(self, p):
            self.points = p * np.array([1.0, 1.0, 0.0])
            self.inside = p[:, 2] < 0
            self.distance = np.abs(p[:, 2])

    class Test:
        tested = np.arange(3)

        def signed(self, body):
            return body[:, 2].copy(), Hit(body)

    body = np.array([[1.0, 0.0, -0.02], [1.2, 0.0, -0.01], [0.5, 0.0, 0.3]])
    axis = pc.fastest_axis(Test(), body, np.zeros(3), clearance=0.01)
    # a point at +x is lifted (+z) fastest by a turn about -y
    assert np.allclose(axis, [0.0, -1.0, 0.0], atol=1e-9)
    turned = body @ pc_rotation(axis, 0.05).T
    assert turned[0, 2] > body[0, 2] and turned[1, 2] > body[1, 2]


def pc_rotation(axis, angle):
    from loosefit.body.rotations import axis_angle_to_matrix

    return axis_angle_to_matrix(np.asarray(axis) * angle).astype(np.float64)
