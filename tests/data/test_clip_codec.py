import json

import numpy as np
import pytest

from loosefit.data.clip_codec import (
    STEP,
    decode_clip,
    decode_vertices,
    encode_clip,
    encode_vertices,
)
from loosefit.errors import LoosefitInputError


def _garment(T, V=7, seed=0, speed=0.01):
    """(T, V, 3) float32 vertices wandering about a metre from the origin."""
    rng = np.random.default_rng(seed)
    walk = np.cumsum(rng.normal(0, speed, (T, V, 3)), axis=0)
    return (walk + rng.uniform(-1, 1, (1, V, 3))).astype(np.float32)


def _quantised(g, step=STEP):
    """The plain answer: every position rounded to the step, as float32."""
    return (np.rint(g.astype(np.float64) / step).astype(np.int64) * step).astype(np.float32)


@pytest.mark.parametrize("T", [1, 2, 3, 40])
def test_vertices_come_back_as_their_quantised_values(T):
    g = _garment(T)
    meta, blob = encode_vertices(g)
    assert meta["shape"] == [T, 7, 3] and meta["step"] == STEP
    out = decode_vertices(meta, blob)
    assert out.dtype == np.float32 and out.shape == g.shape
    np.testing.assert_array_equal(out, _quantised(g))
    assert np.abs(out.astype(np.float64) - g).max() <= STEP / 2 + 1e-7


def test_large_second_differences_take_int32():
    g = _garment(6, speed=0.5)  # jumps of a metre a frame: beyond int16 at 0.02 mm
    meta, blob = encode_vertices(g)
    assert meta["dd_dtype"] == "<i4"
    np.testing.assert_array_equal(decode_vertices(meta, blob), _quantised(g))
    assert encode_vertices(_garment(6))[0]["dd_dtype"] == "<i2"


def test_a_coarser_step():
    g = _garment(5)
    meta, blob = encode_vertices(g, step=1e-3)
    np.testing.assert_array_equal(decode_vertices(meta, blob), _quantised(g, 1e-3))


@pytest.mark.parametrize(
    ("garment", "found"),
    [
        (np.zeros((3, 4, 3), np.float64), "(3, 4, 3) float64"),
        (np.zeros((3, 4), np.float32), "(3, 4) float32"),
        (np.zeros((0, 4, 3), np.float32), "none or NaN/inf"),
        (np.full((2, 4, 3), np.nan, np.float32), "none or NaN/inf"),
        (np.full((2, 4, 3), 2.0e4, np.float32), "2e+04 m"),
    ],
)
def test_vertices_that_cannot_be_coded_are_refused(garment, found):
    with pytest.raises(LoosefitInputError) as err:
        encode_vertices(garment)
    assert err.value.field == "garment_vertices" and err.value.found == found


def test_bytes_of_another_shape_are_refused():
    meta, blob = encode_vertices(_garment(4))
    with pytest.raises(ValueError, match=r"for shape \[5, 7, 3\]"):
        decode_vertices(meta | {"shape": [5, 7, 3]}, blob)


def test_a_clip_keeps_its_other_arrays_exact_and_its_garment_last():
    arrays = {
        "garment_vertices": _garment(9),
        "rotations": np.random.default_rng(1).normal(size=(9, 4, 3, 3)).astype(np.float32),
        "fps": np.array(30.0),
        "name": np.array("spin"),
    }
    buf = encode_clip(arrays)
    n = int.from_bytes(buf[:4], "little")
    head = json.loads(buf[4 : 4 + n])
    assert head["shape"] == [9, 7, 3] and head["rest_npz"] > 0
    out = decode_clip(buf)
    assert list(out) == ["rotations", "fps", "name", "garment_vertices"]
    for k in ("rotations", "fps", "name"):
        np.testing.assert_array_equal(out[k], arrays[k])
        assert out[k].dtype == arrays[k].dtype
    np.testing.assert_array_equal(out["garment_vertices"], _quantised(arrays["garment_vertices"]))
    with pytest.raises(ValueError, match="a header of"):
        decode_clip(buf[: n // 2])
