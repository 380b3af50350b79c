import numpy as np
import pytest

from loosefit.geometry.edges import unique_edges
from loosefit.render.geometry import capsule
from loosefit.render.skeleton_sheet import bone_sticks, skeleton_sheet

# a three-joint chain at two frames: straight up, then bent at the middle joint
POINTS = np.array(
    [
        [[0.0, 0.0, 1.0], [0.0, 0.0, 1.4], [0.0, 0.0, 1.8]],
        [[0.0, 0.0, 1.0], [0.0, 0.0, 1.4], [0.3, 0.0, 1.4]],
    ]
)
BONES = [(0, 1), (1, 2)]


def _distance_to_segment(x, p, q):
    """Distance of points x (N, 3) to the line through p and q (3,)."""
    d = (q - p) / np.linalg.norm(q - p)
    rel = x - p
    return np.linalg.norm(rel - np.outer(rel @ d, d), axis=1)


def test_sticks_are_closed_prisms_round_their_bones():
    faces, vertices = bone_sticks(POINTS, BONES, radius=0.02, sides=6)
    assert vertices.shape == (2, 2 * 6 * 2, 3) and vertices.dtype == np.float32
    assert faces.dtype == np.int64 and faces.max() == 23
    _, counts = unique_edges(faces)
    assert (counts == 2).all()  # closed: caps and sides
    for k in range(2):
        for i, (a, b) in enumerate(BONES):
            ring = vertices[k, 12 * i : 12 * (i + 1)].astype(np.float64)
            p, q = POINTS[k, a], POINTS[k, b]
            np.testing.assert_allclose(_distance_to_segment(ring, p, q), 0.02, atol=1e-6)
            # the first ring round the bone's start, the second round its end
            np.testing.assert_allclose(ring[:6].mean(0), p, atol=1e-6)
            np.testing.assert_allclose(ring[6:].mean(0), q, atol=1e-6)


def test_sticks_face_outward():
    faces, vertices = bone_sticks(POINTS, BONES[:1], radius=0.05, sides=8)
    v = vertices[0].astype(np.float64)
    a, b, c = (v[faces[:, i]] for i in range(3))
    volume = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6  # divergence theorem
    octagon = 0.5 * 8 * 0.05**2 * np.sin(2 * np.pi / 8)
    assert volume == pytest.approx(octagon * 0.4, rel=1e-5)


def test_no_bones_no_sticks():
    faces, vertices = bone_sticks(POINTS, [])
    assert faces.shape == (0, 3) and vertices.shape == (2, 0, 3)


def test_the_sheet_shows_the_skeleton_left_of_the_avatar():
    body_v, body_f = capsule(0.15, 1.7, 16, 16)
    try:
        sheet = skeleton_sheet(POINTS, BONES, np.stack([body_v] * 2), body_f, [3, 7], size=120)
    except RuntimeError as exc:
        pytest.skip(f"no headless OpenGL (EGL) context on this machine: {exc}")
    # two pictures 180 x 120 side by side in one row, 4 pixels apart and round
    assert sheet.shape == (120 + 8, 2 * 180 + 12, 3) and sheet.dtype == np.uint8
    spans = []
    for k in range(2):
        picture = sheet[4:124, 4 + 184 * k : 184 * (k + 1)].astype(int)
        r, g, b = picture[..., 0], picture[..., 1], picture[..., 2]
        blue = (b > r + 40) & (b > g)  # the sticks ("other" meshes are blue), not grey skin
        cols = np.flatnonzero(blue.any(0))
        assert len(cols) and cols.max() < 90  # the skeleton stands left of the avatar
        spans.append(np.ptp(cols))
    # upright at the first frame (a thin line), its second bone level at the second
    assert spans[0] < 5 and spans[1] > 10
