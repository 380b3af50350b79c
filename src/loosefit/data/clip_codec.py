"""The coding of one clip for a pack (:mod:`loosefit.data.pack`): its garment quantised and
compressed, its other arrays exact.

A clip ``sequences/NAME.npz`` travels as ``sequences/NAME.npz.lfv``::

    4 bytes     the length of the JSON header, little-endian
    JSON        {"shape": [T, V, 3], "dd_dtype": "<i2", "step": 2e-05, "rest_npz": bytes}
    rest_npz    an .npz (deflated) of the clip's other arrays, exact
    the rest    lzma of garment_vertices (T, V, 3) quantised to ``step`` (0.02 mm):
                frame 0 and the first difference as int32 (V * 3 each), then the second
                differences in time (T - 2, V, 3), vertex-major, as int16 (int32 where one
                is too large), split into byte planes

The second differences are exact on the quantised positions, so a vertex comes back
within ``step / 2`` (0.01 mm) of the simulated one, plus float32's own rounding (under
0.1 um within 2 m of the origin). This is the coding of the shared corpus's packer
(``../shared/datasets/lfz.py``), and decodes to what it decodes, bit for bit.
"""

from __future__ import annotations

import io
import json
import lzma

import numpy as np

from loosefit.errors import LoosefitInputError

STEP = 2.0e-5  # m, the quantisation of garment_vertices (0.02 mm)
CODED = ".lfv"  # the suffix a clip's member takes


def _planes(a: np.ndarray) -> bytes:
    """(N,) integers -> their bytes, all first bytes, then all second bytes, ..."""
    return a.view(np.uint8).reshape(-1, a.dtype.itemsize).T.copy().tobytes()


def _unplanes(buf: bytes, dtype: np.dtype, count: int) -> np.ndarray:
    b = np.frombuffer(buf, np.uint8).reshape(dtype.itemsize, count).T.copy()
    return b.reshape(-1).view(dtype)  # (count,)


def encode_vertices(garment: np.ndarray, step: float = STEP) -> tuple[dict, bytes]:
    """(T, V, 3) float32 garment vertices -> the header and the compressed bytes.

    Raises:
        LoosefitInputError: not (T, V, 3) float32 with T >= 1, not finite, or further
            than 10 km from the origin (the quantised values would overflow int32).
    """
    if garment.dtype != np.float32 or garment.ndim != 3 or garment.shape[2] != 3:
        raise LoosefitInputError(
            "garment_vertices",
            "garment_vertices",
            "(T, V, 3) float32",
            f"{garment.shape} {garment.dtype}",
        )
    if garment.shape[0] < 1 or not np.isfinite(garment).all():
        raise LoosefitInputError(
            "garment_vertices", "garment_vertices", "at least one frame, finite", "none or NaN/inf"
        )
    reach = float(np.abs(garment).max())
    if reach >= 2**29 * step:  # then the values and their differences fit int32
        raise LoosefitInputError(
            "garment_vertices",
            "garment_vertices",
            f"positions within {2**29 * step / 1e3:.1f} km of the origin",
            f"{reach:.3g} m",
        )
    q = np.rint(garment.astype(np.float64) / step).astype(np.int64)  # (T, V, 3)
    d = np.diff(q, axis=0)  # (T - 1, V, 3)
    dd = np.diff(d, axis=0) if len(q) > 2 else np.zeros((0, *q.shape[1:]), np.int64)
    dd_type = np.int16 if int(np.abs(dd).max(initial=0)) < 32767 else np.int32
    body = np.ascontiguousarray(dd.transpose(1, 2, 0)).astype(dd_type)  # (V, 3, T - 2)
    raw = q[:1].astype(np.int32).tobytes() + d[:1].astype(np.int32).tobytes()
    meta = {"shape": list(garment.shape), "dd_dtype": np.dtype(dd_type).str, "step": step}
    return meta, lzma.compress(raw + _planes(body.reshape(-1)), preset=6)


def decode_vertices(meta: dict, blob: bytes) -> np.ndarray:
    """The header and bytes of :func:`encode_vertices` -> (T, V, 3) float32.

    Raises:
        ValueError: the bytes do not decode to the header's shape (lzma.LZMAError too).
    """
    T, V, C = (int(n) for n in meta["shape"])
    dd_type = np.dtype(meta["dd_dtype"])
    raw = lzma.decompress(blob)
    n = V * C
    size = 4 * n if T == 1 else 8 * n + (T - 2) * n * dd_type.itemsize
    if T < 1 or len(raw) != size:
        raise ValueError(f"{len(raw)} bytes for shape {meta['shape']} (expected {size})")
    head = np.frombuffer(raw[: 4 * n], np.int32).reshape(1, V, C).astype(np.int64)
    if T == 1:
        return (head * meta["step"]).astype(np.float32)
    d0 = np.frombuffer(raw[4 * n : 8 * n], np.int32).reshape(1, V, C).astype(np.int64)
    dd = _unplanes(raw[8 * n :], dd_type, (T - 2) * n).astype(np.int64)
    dd = dd.reshape(V, C, T - 2).transpose(2, 0, 1)  # (T - 2, V, 3)
    d = np.concatenate([d0, d0 + np.cumsum(dd, axis=0)], axis=0)  # (T - 1, V, 3)
    q = np.concatenate([head, head + np.cumsum(d, axis=0)], axis=0)  # (T, V, 3)
    return (q * meta["step"]).astype(np.float32)


def encode_clip(arrays: dict[str, np.ndarray], step: float = STEP) -> bytes:
    """A clip's arrays (``garment_vertices`` among them) -> its ``.lfv`` member."""
    rest = io.BytesIO()
    np.savez_compressed(rest, **{k: v for k, v in arrays.items() if k != "garment_vertices"})
    meta, blob = encode_vertices(arrays["garment_vertices"], step)
    meta["rest_npz"] = len(rest.getvalue())
    head = json.dumps(meta).encode()
    return len(head).to_bytes(4, "little") + head + rest.getvalue() + blob


def decode_clip(buf: bytes) -> dict[str, np.ndarray]:
    """A ``.lfv`` member -> the clip's arrays, ``garment_vertices`` last.

    Raises:
        ValueError: a damaged member (lzma.LZMAError, zipfile.BadZipFile and
            json.JSONDecodeError among its kinds).
    """
    n = int.from_bytes(buf[:4], "little")
    if len(buf) < 4 + n:
        raise ValueError(f"a header of {n} bytes in a member of {len(buf)}")
    meta = json.loads(buf[4 : 4 + n])
    end = 4 + n + int(meta["rest_npz"])
    with np.load(io.BytesIO(buf[4 + n : end]), allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["garment_vertices"] = decode_vertices(meta, buf[end:])
    return arrays
