import numpy as np
import pytest

from loosefit.motion.capture_measure import (
    HEAD_ANKLE_TO_HEIGHT,
    LEG_TO_HEIGHT,
    face_forward,
    guess_up,
    matching_frames,
    measure_height,
)

NAMES = ["Hips", "Spine", "Head", "LeftFoot", "RightFoot"]


def _standing(up_axis: int, sign: float, frames: int = 3) -> np.ndarray:
    """(T, 5, 3) joints of NAMES: the head 1.5 m from the feet along ``sign`` * axis."""
    height = np.array([0.9, 1.2, 1.5, 0.0, 0.0])
    pos = np.zeros((frames, 5, 3))
    pos[..., up_axis] = sign * height
    pos[:, 3, (up_axis + 1) % 3] = 0.1  # the feet apart, across
    pos[:, 4, (up_axis + 1) % 3] = -0.1
    return pos


@pytest.mark.parametrize(("axis", "sign", "up"), [(1, 1, "+y"), (2, -1, "-z"), (0, 1, "+x")])
def test_up_is_the_axis_from_the_feet_to_the_head(axis, sign, up):
    assert guess_up(NAMES, _standing(axis, sign)) == up


def test_no_up_without_a_head_or_feet_or_a_clear_axis():
    pos = _standing(1, 1)
    assert guess_up(["Hips", "Spine", "Neck", "LeftHand", "RightHand"], pos) is None
    leaning = pos.copy()
    leaning[:, 2, [0, 2]] = [1.5, 1.0]  # the head as far aside as up: no axis holds 70 %
    assert guess_up(NAMES, leaning) is None


def test_matching_frames_are_the_first_middle_and_quarters_once_each():
    assert matching_frames(100) == [0, 50, 25, 75]
    assert matching_frames(3) == [0, 1, 2]
    assert matching_frames(2) == [0, 1]
    assert matching_frames(1) == [0]


def test_face_forward_turns_the_forward_onto_minus_y_about_up():
    points = np.array([[1.0, 0.0, 0.5], [0.0, 1.0, 2.0], [0.3, -0.4, 1.0]])
    for forward in ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-0.6, 0.8, 0.0]):
        turned = face_forward(np.vstack([points, forward]), np.array(forward))
        np.testing.assert_allclose(turned[-1], [0.0, -1.0, 0.0], atol=1e-12)
        np.testing.assert_allclose(turned[:3, 2], points[:, 2])  # heights kept
        d = np.linalg.norm(turned[:3, None] - turned[None, :3], axis=-1)
        np.testing.assert_allclose(d, np.linalg.norm(points[:, None] - points[None], axis=-1))


def _legs(frames: int, head_z: np.ndarray):
    """(T, 8, 3) joints: hips, both legs of 0.45 + 0.4 m, straight down, and a head."""
    names = ["Hips", "LeftUpLeg", "LeftLeg", "LeftFoot", "RightUpLeg", "RightLeg", "RightFoot"]
    pos = np.zeros((frames, 8, 3))
    for side, x in ((1, 0.1), (4, -0.1)):
        pos[:, side : side + 3, 0] = x
        pos[:, side : side + 3, 2] = [0.85, 0.4, 0.0]
    pos[:, 7, 2] = head_z
    present = {n: i for i, n in enumerate(names)} | {"Head": 7}
    return pos, present


def test_height_from_the_most_extended_frame():
    pos, present = _legs(3, np.array([1.3, 1.4, 1.35]))
    m = measure_height(pos, present)
    assert m.frame == 1
    assert m.height == pytest.approx(1.4 / HEAD_ANKLE_TO_HEIGHT)
    assert "frame 1, the most extended" in m.how


def test_height_from_the_legs_when_the_dancer_never_stands_straight():
    pos, present = _legs(2, np.array([0.9, 1.0]))  # crouching throughout
    m = measure_height(pos, present)
    assert m.frame is None
    assert m.height == pytest.approx(0.85 / LEG_TO_HEIGHT)
    assert "never stands straight" in m.how
    no_head = {k: v for k, v in present.items() if k != "Head"}
    assert measure_height(pos, no_head).height == pytest.approx(0.85 / LEG_TO_HEIGHT)


def test_height_from_the_median_frame_extent_without_head_or_legs():
    pos = np.zeros((3, 2, 3))
    pos[:, 1, 2] = [1.0, 3.0, 2.0]
    extra = np.zeros((3, 1, 3))
    extra[:, 0, 2] = -0.5  # an End Site below the joints
    m = measure_height(pos, {}, extra)
    assert (m.frame, m.height) == (2, 2.5)
    assert "median frame" in m.how
