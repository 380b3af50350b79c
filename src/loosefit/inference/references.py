"""Two garments that are not models, the references that error tables set a rollout against:
the settled drape carried rigidly (no dynamics at all) and the simulation through the
generative model (the floor under any motion encoder's error)."""

from __future__ import annotations

import time

import numpy as np
import torch

from loosefit.inference.rollout import RolloutResult, motion_root_frames
from loosefit.inference.timeline import RolloutConfig
from loosefit.model.generative import GarmentGenerativeModel
from loosefit.model.motion_features import from_root_frame, to_root_frame
from loosefit.types import Motion


@torch.no_grad()
def carried_drape(
    motion: Motion,
    rest_state: torch.Tensor,
    floor_height: float,
    config: RolloutConfig | None = None,
) -> RolloutResult:
    """The settled drape carried rigidly by the root frame: a garment with no dynamics at all.

    Not a model: the reference that error tables set a learned rollout against (a
    rollout that does no better has learned nothing of the motion). Frame ``t`` is
    ``rest_state`` placed in the root frame (heading and origin) of motion frame ``t``.

    Args:
        motion: T frames.
        rest_state: (V, 3) the settled drape in the rest pose's root frame.
        floor_height: the avatar's standing root height (for the timeline, as in a rollout).
        config: the preroll (only its length matters here).

    Returns:
        :class:`~loosefit.inference.rollout.RolloutResult` with (T, V, 3) world positions.
    """
    t0 = time.perf_counter()
    H, p, P = motion_root_frames(motion, floor_height, config)
    rest = rest_state.detach().float().cpu()[None].expand(len(H), -1, -1)
    out = from_root_frame(rest, H, p)
    return RolloutResult(out.numpy(), time.perf_counter() - t0, P + len(H))


@torch.no_grad()
def reconstruction(
    generative: GarmentGenerativeModel,
    motion: Motion,
    truth: np.ndarray,
    floor_height: float,
    config: RolloutConfig | None = None,
    chunk: int = 128,
) -> RolloutResult:
    """The simulated garment through the generative model: its own code Z*, decoded.

    Not a model either: the floor under any motion encoder's error, since a motion
    encoder can do no better than map each frame to the code the generative encoder
    gives the simulated garment (Eq. 12's Z*) and the frozen decoders decode it.

    Args:
        generative: the generative stage.
        motion: T frames (only the root frames matter).
        truth: (T, V, 3) the simulated garment, world positions.
        floor_height, config: as in a rollout (the root frames of the motion frames).
        chunk: frames per network call.

    Returns:
        :class:`~loosefit.inference.rollout.RolloutResult` with (T, V, 3) world positions.
    """
    t0 = time.perf_counter()
    H, p, _ = motion_root_frames(motion, floor_height, config)
    local = to_root_frame(torch.as_tensor(truth, dtype=torch.float32), H, p)
    world = from_root_frame(generative.reconstruct_all(local, chunk), H, p)
    return RolloutResult(world.numpy(), time.perf_counter() - t0, int(len(local)))
