import math

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.render.camera import (
    CameraView,
    camera_track,
    fit_distance,
    light_track,
    look_at,
    named_view,
    orthographic,
    perspective,
    smooth_track,
    view_matrices,
)


def _ndc(view, proj, points):
    """(N, 3) normalised device coordinates of world points (N, 3)."""
    h = np.c_[points, np.ones(len(points))] @ (proj.astype(np.float64) @ view).T  # (N, 4)
    return h[:, :3] / h[:, 3:]


def test_look_at_is_a_rigid_map_that_keeps_up_upwards():
    m = look_at((3.0, -4.0, 2.0), (0.0, 0.0, 1.0)).astype(np.float64)
    np.testing.assert_allclose(m[:3, :3] @ m[:3, :3].T, np.eye(3), atol=1e-6)
    assert np.linalg.det(m[:3, :3]) > 0
    up = m[:3, :3] @ np.array([0.0, 0.0, 1.0])  # the world's up, in camera space
    assert up[1] > 0 and abs(up[0]) < 1e-6


def test_look_at_refuses_a_camera_on_its_target_or_an_up_along_the_view():
    with pytest.raises(LoosefitInputError, match="field 'target - eye'"):
        look_at((1.0, 2.0, 3.0), (1.0, 2.0, 3.0))
    with pytest.raises(LoosefitInputError, match="not parallel to the viewing direction"):
        look_at((0.0, 0.0, 5.0), (0.0, 0.0, 0.0), up=(0.0, 0.0, 2.0))


def test_perspective_field_of_view_and_aspect():
    proj = perspective(60.0, 2.0, 0.1, 10.0)
    # a point at depth 3 on the top edge of the view, and one on the right edge
    y = 3.0 * math.tan(math.radians(30.0))
    ndc = _ndc(np.eye(4), proj, np.array([[0.0, y, -3.0], [2.0 * y, 0.0, -3.0]]))
    np.testing.assert_allclose(ndc[:, :2], [[0.0, 1.0], [1.0, 0.0]], atol=1e-6)
    with pytest.raises(LoosefitInputError, match="0 < fov < 180.*found 30.0, 1.0, 2.0, 1.0"):
        perspective(30.0, 1.0, 2.0, 1.0)


def test_orthographic_maps_its_box_to_the_unit_cube():
    proj = orthographic(-1.0, 3.0, 2.0, 4.0, -1.0, 5.0)
    corners = np.array([[-1.0, 2.0, 1.0], [3.0, 4.0, -5.0]])  # z = -near and z = -far
    np.testing.assert_allclose(_ndc(np.eye(4), proj, corners), [[-1, -1, -1], [1, 1, 1]])
    with pytest.raises(LoosefitInputError, match="right > left"):
        orthographic(1.0, 1.0, 0.0, 1.0, 0.0, 1.0)


def test_named_views_pass_through_and_unknown_names_are_refused():
    custom = CameraView("low", 30.0, -5.0)
    assert named_view(custom) is custom
    assert named_view("side").azimuth_deg == 90.0
    with pytest.raises(LoosefitInputError, match=r"one of \['front', 'side'"):
        named_view("left")


@pytest.mark.parametrize("view", ["front", "three_quarter", "top", CameraView("low", 200, -20)])
def test_fitted_distance_puts_the_farthest_corner_on_the_margin(view):
    view = named_view(view)
    lo, hi, aspect = np.array([-0.3, -0.2, 0.0]), np.array([0.5, 0.25, 1.8]), 1.5
    v, p = view_matrices(view, lo, hi, aspect)
    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)])
    ndc = _ndc(v, p, lo + corners * (hi - lo))
    # the box fills the picture up to the margin, exactly: its widest corner on the edge
    assert np.abs(ndc[:, :2]).max() == pytest.approx(1 / view.margin, abs=1e-4)
    eye = np.linalg.inv(v.astype(np.float64))[:3, 3]
    assert np.linalg.norm(eye - (lo + hi) / 2) == pytest.approx(
        fit_distance(view, lo, hi, aspect), rel=1e-5
    )


def _naive_smooth(points, sigma):
    """The Gaussian of each frame over its neighbours, the ends reflected through the end
    point (2 x[0] - x[k] before the start), one frame at a time."""
    r = math.ceil(3 * sigma)
    T = len(points)

    def at(i):
        if i < 0:
            return 2 * points[0] - points[-i]
        if i >= T:
            return 2 * points[-1] - points[2 * (T - 1) - i]
        return points[i]

    out = np.zeros_like(points)
    for t in range(T):
        w = np.array([math.exp(-0.5 * (k / sigma) ** 2) for k in range(-r, r + 1)])
        out[t] = sum(wk * at(t + k) for wk, k in zip(w / w.sum(), range(-r, r + 1), strict=True))
    return out


def test_smooth_track_is_the_plain_gaussian_and_keeps_straight_lines():
    rng = np.random.default_rng(0)
    track = rng.normal(size=(20, 2))
    np.testing.assert_allclose(smooth_track(track, 1.5), _naive_smooth(track, 1.5), atol=1e-12)
    line = np.linspace([0.0, 1.0], [2.0, -1.0], 15)
    np.testing.assert_allclose(smooth_track(line, 3.0), line, atol=1e-12)
    np.testing.assert_array_equal(smooth_track(track, 0.0), track)


def test_a_following_camera_keeps_its_distance_and_height():
    T = 6
    centres = np.c_[np.linspace(0, 1, T), np.zeros(T), np.full(T, 1.0)]
    lo, hi = centres - 0.3, centres + 0.3
    track = camera_track(["front", "side"], lo, hi, follow_centres=centres, follow_sigma_frames=1)
    assert track.names == ["front", "side"]
    assert track.view.shape == (T, 2, 4, 4) and track.eye.shape == (T, 2, 3)
    gap = np.linalg.norm(track.eye - track.target[:, None], axis=-1)  # (T, 2)
    np.testing.assert_allclose(gap, gap[:1].repeat(T, 0), rtol=1e-5)
    np.testing.assert_allclose(track.target[:, 2], track.target[0, 2])
    np.testing.assert_allclose(track.target[:, 0], smooth_track(centres[:, :2], 1)[:, 0], atol=1e-6)
    with pytest.raises(LoosefitInputError, match=r"follow_centres.*shape \(6, 3\).*\(5, 3\)"):
        camera_track(["front"], lo, hi, follow_centres=centres[:5])


def test_the_light_camera_holds_every_frame_and_snaps_to_texels():
    T = 4
    lo = np.c_[np.linspace(0, 0.9, T), np.zeros(T), np.zeros(T)]
    hi = lo + [0.5, 0.4, 1.7]
    view, proj = light_track((0.5, -0.7, 1.3), lo, hi, map_size=256)
    assert view.shape == proj.shape == (T, 4, 4)
    np.testing.assert_array_equal(view, view[:1].repeat(T, 0))
    signs = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)])
    for t in range(T):
        ndc = _ndc(view[t], proj[t], lo[t] + signs * (hi[t] - lo[t]))
        assert (np.abs(ndc) <= 1.0).all()
    # the boxes are all one size, their centres whole texels apart
    width = 2 / proj[:, 0, 0].astype(np.float64)
    np.testing.assert_allclose(width, width[0])
    centres = -proj[:, 0, 3].astype(np.float64) * width / 2
    texels = centres / (width[0] / 256)
    np.testing.assert_allclose(texels, np.round(texels), atol=1e-2)
    with pytest.raises(LoosefitInputError, match="light_dir"):
        light_track((0.0, 0.0, 0.0), lo, hi, 256)
