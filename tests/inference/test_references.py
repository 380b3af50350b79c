"""The references error tables set a rollout against: the drape carried rigidly by the root
frame, each frame checked against the rotation and translation written out by hand."""

from __future__ import annotations

import numpy as np
import torch

from loosefit.inference.references import carried_drape
from loosefit.inference.timeline import RolloutConfig
from loosefit.types import Motion


def _rz(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]], np.float32)


def test_the_drape_is_carried_by_the_root_s_heading_and_position():
    T = 4
    yaws = np.array([0.0, np.pi / 2, np.pi, -np.pi / 4])
    rot = np.tile(np.eye(3, dtype=np.float32), (T, 2, 1, 1))
    rot[:, 0] = [_rz(a) for a in yaws]
    root = np.array([[0, 0, 1.0], [1, 2, 1.0], [-1, 0.5, 0.9], [0.2, 0.2, 1.1]], np.float32)
    motion = Motion(("Hips", "Spine"), rot, root, 30.0, "turn")
    rest = torch.tensor([[1.0, 0.0, 0.0], [0.0, -0.5, -0.3], [0.2, 0.1, -0.6]])
    result = carried_drape(motion, rest, 0.9, RolloutConfig(warm_frames=2, blend_seconds=0.1))
    assert result.vertices.shape == (T, 3, 3) and result.vertices.dtype == np.float32
    for t in range(T):  # frame t: the rest state turned by the root's yaw, moved to the root
        want = rest.numpy() @ _rz(yaws[t]).T + root[t]
        np.testing.assert_allclose(result.vertices[t], want, atol=1e-5, err_msg=f"frame {t}")
    np.testing.assert_allclose(result.vertices[1, 0], [1.0, 3.0, 1.0], atol=1e-5)  # by hand
    assert result.frames == 2 + 3 + T  # the preroll is counted, as in a rollout
