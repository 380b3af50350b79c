"""How fast a motion turns about the vertical: its heading and the rate it changes.

The heading is the yaw of the root's forward axis
(:func:`~loosefit.model.motion_features.heading_yaw`), computed in the rotations' own
dtype. Its rate is differenced in one of two ways, each kept for the figures that use it:

* ``"gradient"``: the heading unwrapped, then :func:`numpy.gradient` (centred differences
  inside, one-sided at the ends): (T,) values;
* ``"step"``: each step between consecutive frames wrapped to ``[-pi, pi]``: (T - 1,) values.
"""

from __future__ import annotations

import numpy as np

DIFFERENCES = ("gradient", "step")


def heading(root_rotations: np.ndarray) -> np.ndarray:
    """(T,) rad, the heading (yaw about +Z) of each frame's root rotation (T, 3, 3), in
    ``root_rotations``' dtype."""
    import torch

    from loosefit.model.motion_features import heading_yaw

    return heading_yaw(torch.from_numpy(np.asarray(root_rotations))).numpy()


def yaw_rate(root_rotations: np.ndarray, fps: float, difference: str = "gradient") -> np.ndarray:
    """rad/s, how fast the heading turns (+ is counter-clockwise seen from above).

    Args:
        root_rotations: (T, 3, 3) the root joint's world rotation (rest to posed), T >= 2.
        fps: frames per second.
        difference: ``"gradient"`` ((T,) values) or ``"step"`` ((T - 1,) values), see the
            module's docstring.
    """
    yaw = heading(root_rotations)
    if difference == "gradient":
        return np.gradient(np.unwrap(yaw)) * fps
    if difference == "step":
        return np.angle(np.exp(1j * np.diff(yaw))) * fps
    raise ValueError(f"difference must be one of {DIFFERENCES}, not {difference!r}")


def turn_rate(
    root_rotations: np.ndarray, fps: float, window: int = 5, difference: str = "step"
) -> np.ndarray:
    """(T,) rad/s, the speed of the heading's turn, a centred mean over ``window`` frames.

    Args:
        root_rotations: (T, 3, 3) root rotations, T >= 2.
        fps: frames per second.
        window: frames averaged (``numpy.convolve(..., mode="same")``).
        difference: as :func:`yaw_rate`; with ``"step"`` the first frame is 0 and the mean
            runs over the T - 1 steps.
    """
    rate = np.abs(yaw_rate(root_rotations, fps, difference))
    smooth = np.convolve(rate, np.ones(window) / window, mode="same")
    return np.concatenate([[0.0], smooth]) if difference == "step" else smooth


def fastest_turn(
    root_rotations: np.ndarray, fps: float, window: int = 5, difference: str = "step"
) -> int:
    """The frame of :func:`turn_rate`'s largest value (with ``"step"``, frame 0 left out)."""
    rate = turn_rate(root_rotations, fps, window, difference)
    if difference == "step":
        return int(np.argmax(rate[1:])) + 1
    return int(np.argmax(rate))
