"""What a model that animates a garment offers, as :class:`typing.Protocol`s: the paper's
stages (:class:`~loosefit.inference.animator.AnimationModel`) and the baselines
(:class:`~loosefit.inference.baseline.BaselineModel`) both satisfy :class:`AnimatingModel`;
only ours animates N motions at once (:class:`BatchAnimatingModel`) and has learned stages
to export (:class:`LearnedStages`). The API, the CLI, the evaluation and the ONNX export
check a model against these instead of asking for its class. Nothing is imported here at
run time but the standard library.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Protocol, runtime_checkable

if TYPE_CHECKING:
    import numpy as np
    import torch

    from loosefit.inference.rollout import RolloutResult
    from loosefit.inference.stages import Stages
    from loosefit.inference.timeline import RolloutConfig
    from loosefit.model.generative import GarmentGenerativeModel
    from loosefit.model.motion_encoder import DynamicMotionEncoder
    from loosefit.types import GarmentTemplate, Motion


@runtime_checkable
class AnimatingModel(Protocol):
    """A trained model that animates its garment through a motion."""

    template: GarmentTemplate  # the garment it animates (V vertices)
    joint_names: tuple[str, ...]  # the skeleton a motion must be on
    fps: float  # the frame rate it was trained at
    floor_height: float  # the avatar's standing root height
    body: dict  # the avatar's record (its shape)
    rollout_config: RolloutConfig  # the timeline before a motion's first frame
    path: Path  # the checkpoint it came from
    stages: Stages  # what animate() runs by default

    def avatar(self):
        """The body the garment was simulated on."""
        ...

    def check_motion(self, motion: Motion) -> None:
        """A clear error for a motion on other joints or not finite."""
        ...

    def animate(
        self,
        motion: Motion,
        progress: Callable[[int, int], None] | None = None,
        truth: np.ndarray | None = None,
        restart_every: int | None = None,
        stages: Stages | None = None,
        runtime: str = "torch",
        *,
        collision: str = "full",
    ) -> RolloutResult:
        """The garment through ``motion``: (T, V, 3) world positions in the result."""
        ...


@runtime_checkable
class BatchAnimatingModel(AnimatingModel, Protocol):
    """A model that also animates N motions at once (N characters)."""

    def animate_batch(
        self,
        motions: list[Motion],
        progress: Callable[[int, int], None] | None = None,
        stages: Stages | None = None,
        runtime: str = "torch",
        collision: str = "full",
    ) -> list[RolloutResult]:
        """One result per motion."""
        ...


@runtime_checkable
class LearnedStages(Protocol):
    """The paper's learned stages, what the ONNX graphs are built from."""

    generative: GarmentGenerativeModel  # the decoders
    encoder: DynamicMotionEncoder  # the motion stage
    detail: torch.nn.Module | None  # the detail generator, if trained
    template: GarmentTemplate
    rest_state: torch.Tensor  # (V, 3)
    joint_names: tuple[str, ...]
    floor_height: float
    fps: float
    rollout_config: RolloutConfig
    path: Path
