"""The release of trapped cloth (loosefit.sim.release) on boxes."""

from __future__ import annotations

import numpy as np

from loosefit.sim.release import TrappedRelease


def _release(v, f, parts=None, n=1, depth=0.05):
    parts = np.zeros(len(v), np.int64) if parts is None else parts
    return TrappedRelease(v, (f,), parts, n, depth, 0.004)


def test_release_puts_deep_cloth_back_on_the_moving_skin():
    from tests.meshes import cube

    v, f = cube(1.0)  # centred at the origin, outward normals
    before, after = v - np.array([0.1, 0.0, 0.0]), v  # the box moved 0.1 m along +x
    x = np.array([[0.0, 0.0, 0.3], [0.0, 0.0, 0.49], [0.0, 0.0, 0.7]], np.float32)
    qd = np.ones_like(x)
    y, yd, moved = _release(after, f, n=3).step(x, qd, after, before, frame_dt=0.5)
    assert moved == 1
    # the deep one (0.2 m in), never seen outside, goes to the closest face (the top),
    # 4 mm out, with the box's velocity
    np.testing.assert_allclose(y[0], [0.0, 0.0, 0.504], atol=1e-5)
    np.testing.assert_allclose(yd[0], [0.2, 0.0, 0.0], atol=1e-5)
    # 1 cm in (within depth) and outside: untouched
    np.testing.assert_array_equal(y[1:], x[1:])
    np.testing.assert_array_equal(yd[1:], qd[1:])
    assert _release(after, f, n=3, depth=0.25).step(x, qd, after, before, 0.5)[2] == 0


def test_release_puts_cloth_back_on_the_side_it_went_in_from():
    from tests.meshes import cube

    v, f = cube(1.0)
    release = _release(v, f, n=2)
    x = np.array([[0.1, 0.0, 0.6], [0.0, 0.0, 2.0]], np.float32)  # over the top face
    qd = np.zeros_like(x)
    assert release.step(x, qd, v, v, 1 / 30)[2] == 0 and (release.face >= 0).all()
    anchors = release.face.copy()
    # the first one is pushed through to 0.4 m under the top, 0.1 m over the bottom: the
    # closest face is the bottom, but it went in at the top, where it goes back
    x[0] = [0.1, 0.0, -0.4]
    y, _, moved = release.step(x, qd, v, v, 1 / 30)
    assert moved == 1
    np.testing.assert_allclose(y[0], [0.1, 0.0, 0.504], atol=1e-5)
    np.testing.assert_array_equal(release.face, anchors)  # it was inside: anchor kept


def test_release_anchors_on_the_part_the_cloth_is_caught_in():
    from tests.meshes import cube

    a, fa = cube(1.0)  # part 0, x in [-0.5, 0.5]
    b, fb = cube(1.0)  # part 1, x in [0.7, 1.7]: 0.2 m apart
    v = np.concatenate([a, b + np.array([1.2, 0.0, 0.0])]).astype(np.float32)
    f = np.concatenate([fa, fb + len(a)])
    parts = np.repeat([0, 1], len(a))
    release = _release(v, f, parts)
    x = np.array([[0.65, 0.0, 0.0]], np.float32)  # between the two, nearer part 1
    qd = np.zeros_like(x)
    release.step(x, qd, v, v, 1 / 30)
    # pressed 0.2 m into part 0: back onto part 0 where it went in (x = 0.5), not onto
    # part 1, the closest skin when it was last outside
    x[0] = [0.3, 0.0, 0.0]
    y, _, moved = release.step(x, qd, v, v, 1 / 30)
    assert moved == 1
    np.testing.assert_allclose(y[0], [0.504, 0.0, 0.0], atol=1e-5)
