"""glTF animation samplers: interpolation as glTF 2.0 specifies it, and the frame rate rule."""

import numpy as np

from loosefit.motion.gltf_animation import DEFAULT_FPS, frame_times, sample_channel


def test_samplers_interpolate_as_gltf_says():
    t = np.array([0.0, 1.0, 2.0])
    v = np.array([[0.0], [10.0], [0.0]])
    at = np.array([-1.0, 0.25, 1.0, 1.5, 3.0])
    assert sample_channel(t, v, "LINEAR", at, False)[:, 0].tolist() == [0, 2.5, 10, 5, 0]
    assert sample_channel(t, v, "STEP", at, False)[:, 0].tolist() == [0, 0, 10, 10, 0]
    # Cubic: tangents of t^3 (3 t^2) reproduce it exactly between keys.
    f, df = t**3, 3 * t**2
    cubic = np.stack([df, f, df], 1).reshape(-1, 1)  # in-tangent, value, out-tangent per key
    x = np.linspace(0, 2, 9)
    assert np.allclose(sample_channel(t, cubic, "CUBICSPLINE", x, False)[:, 0], x**3)
    # Rotations: slerp halfway from identity to a quarter turn about z is an eighth turn.
    s = np.sin(np.pi / 4)
    q = np.array([[0, 0, 0, 1.0], [0, 0, s, s]])
    half = sample_channel(t[:2], q, "LINEAR", np.array([0.5]), True)[0]
    assert np.allclose(half, [0, 0, np.sin(np.pi / 8), np.cos(np.pi / 8)])
    # The short way round: a key written with the opposite sign changes nothing.
    assert np.allclose(
        sample_channel(t[:2], q * [[1], [-1]], "LINEAR", np.array([0.5]), True), half[None]
    ) or np.allclose(
        -sample_channel(t[:2], q * [[1], [-1]], "LINEAR", np.array([0.5]), True), half[None]
    )


def _channels(*times):
    """Channels on nodes 0, 1, ...: each its keyframe times, zero values."""
    return {
        (n, "translation"): (np.asarray(t), np.zeros((len(t), 3)), "LINEAR")
        for n, t in enumerate(times)
    }


def test_the_densest_keyframes_set_the_rate_from_the_first_key_to_the_last():
    # 24 keys a second on one channel, 5 on the other: 24 fps over the union of both
    got = frame_times(None, 0, _channels(np.arange(25) / 24, 0.5 + np.arange(6) / 5), None)
    assert (got.fps, got.how, got.t0, got.t1) == (24.0, "the keyframes' rate", 0.0, 1.5)
    np.testing.assert_allclose(got.at, np.arange(37) / 24)
    # a rate within 0.5 % of a whole one is rounded (float32 times)
    near = frame_times(None, 0, _channels((np.arange(31) / 30).astype(np.float32)), None)
    assert near.fps == 30.0 and len(near.at) == 31


def test_sparse_or_single_keys_take_the_default_rate_and_an_asked_rate_wins():
    sparse = frame_times(None, 0, _channels(np.array([0.0, 0.5, 1.0])), None)
    assert sparse.fps == DEFAULT_FPS and "sparse" in sparse.how and len(sparse.at) == 31
    single = frame_times(None, 0, _channels(np.array([2.0])), None)
    assert single.fps == DEFAULT_FPS and single.at.tolist() == [2.0]
    asked = frame_times(None, 0, _channels(np.arange(25) / 24), 10.0)
    assert (asked.fps, asked.how, len(asked.at)) == (10.0, "as asked", 11)
