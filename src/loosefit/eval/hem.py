"""The hem ring's signals over a sequence: how far it flares, how fast it moves, how it tilts.

Pure functions of world positions (+Z up), used to judge a skirt's swing against the
simulation's (:mod:`loosefit.eval.ensemble`) and its response to the pelvis's pitch
(``bench/quality/pitch_response.py``).
"""

from __future__ import annotations

import numpy as np


def hem_flare(garment: np.ndarray, pelvis: np.ndarray, hem: np.ndarray) -> np.ndarray:
    """(T,) the hem's mean horizontal distance (m) from the pelvis's vertical axis (+Z up).

    Args:
        garment: (T, V, 3) world positions.
        pelvis: (T, 3) the root joint's world position.
        hem: (H,) the hem ring's vertices.
    """
    d = np.asarray(garment, np.float64)[:, hem, :2] - np.asarray(pelvis, np.float64)[:, None, :2]
    return np.linalg.norm(d, axis=-1).mean(-1)


def hem_tilt(
    garment: np.ndarray, pelvis: np.ndarray, forward: np.ndarray, hem: np.ndarray
) -> np.ndarray:
    """(T,) metres: the hem's mean height in front of the pelvis minus behind it, front and
    back along the heading (positive when the front of the hem rides higher).

    Args:
        garment: (T, V, 3) world positions.
        pelvis: (T, 3) the root joint's world position.
        forward: (T, 3) the way the pelvis faces; its horizontal part is the heading.
        hem: (H,) the hem ring's vertices.
    """
    f = np.asarray(forward, np.float64) * np.array([1.0, 1.0, 0.0])
    f /= np.linalg.norm(f, axis=1, keepdims=True)
    ring = np.asarray(garment, np.float64)[:, hem]  # (T, H, 3)
    ahead = ((ring - np.asarray(pelvis, np.float64)[:, None]) * f[:, None]).sum(-1) > 0
    z = ring[..., 2]
    front = (z * ahead).sum(1) / np.maximum(ahead.sum(1), 1)
    back = (z * ~ahead).sum(1) / np.maximum((~ahead).sum(1), 1)
    return front - back


def hem_speed(garment: np.ndarray, hem: np.ndarray, fps: float) -> np.ndarray:
    """(T,) the hem ring's mean vertex speed (m/s), backward differences (the first frame 0)."""
    x = np.asarray(garment, np.float64)[:, hem]
    v = np.zeros(len(x))
    v[1:] = np.linalg.norm(np.diff(x, axis=0), axis=-1).mean(-1) * fps
    return v
