"""Which garment, avatar and cloth configuration a data set or a checkpoint belongs to."""

from __future__ import annotations

import hashlib
import json

import numpy as np

from loosefit.types import GarmentTemplate


def same_garment(a: GarmentTemplate, b: GarmentTemplate, tolerance: float = 1.0e-4) -> bool:
    """The same triangles and rest shapes within ``tolerance`` (m).

    What data and checkpoints are matched by: the fingerprint hashes rounded positions,
    and the same garment built on two machines can differ by a float's last bit, which
    rounding can turn into another digit.
    """
    va, vb = np.asarray(a.vertices), np.asarray(b.vertices)
    fa, fb = np.asarray(a.faces), np.asarray(b.faces)
    return (
        va.shape == vb.shape
        and fa.shape == fb.shape
        and bool(np.array_equal(fa, fb))
        and float(np.abs(va - vb).max(initial=0.0)) <= tolerance
    )


def garment_fingerprint(vertices: np.ndarray, faces: np.ndarray) -> str:
    """A short hash of a garment's rest shape (V, 3) and triangles (F, 3), to match
    checkpoints to data."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(np.round(vertices, 5), np.float32).tobytes())
    h.update(np.ascontiguousarray(faces, np.int64).tobytes())
    return h.hexdigest()[:16]


def avatar_key(avatar: dict) -> tuple[str, tuple[tuple[str, float], ...]]:
    """An avatar description ``{"rig": ..., "shape": {...}}`` in a comparable form: the
    rig (default ``cmu_mb``) and every phenotype (a missing one at the avatar's default,
    as :class:`~loosefit.body.avatar.Avatar` builds it), sorted, rounded to 1e-6."""
    from loosefit.body.avatar import DEFAULT_SHAPE

    shape = {**DEFAULT_SHAPE, **(avatar.get("shape", {}) or {})}
    return (
        str(avatar.get("rig", "cmu_mb")),
        tuple(sorted((str(k), round(float(v), 6)) for k, v in shape.items())),
    )


def avatar_fingerprint(avatar: dict) -> str:
    """A short hash of an avatar description (:func:`avatar_key`)."""
    return hashlib.sha256(json.dumps(avatar_key(avatar)).encode()).hexdigest()[:16]


def cloth_fingerprint(cloth: dict) -> str:
    """A short hash of a cloth configuration as a data set's manifest stores it (the
    fields of :class:`~loosefit.sim.cloth_config.ClothConfig` as JSON), to tell the clips of one
    data set simulated under another.

    The device is normalised to ``"cpu"``: a clip simulated on a GPU is the same data as
    one simulated on the CPU (up to rounding), and a data set may be begun on one and
    finished on the other.
    """
    text = json.dumps(_canonical({**cloth, "device": "cpu"}), sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _canonical(x):
    """Numbers as floats (a config file's ``1`` is the default's ``1.0``), tuples as lists."""
    if isinstance(x, dict):
        return {str(k): _canonical(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_canonical(v) for v in x]
    if isinstance(x, int) and not isinstance(x, bool):
        return float(x)
    return x
