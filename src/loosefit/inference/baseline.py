"""The baselines (Santesteban et al. 2019, virtual bones) as models that animate alike."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import torch

from loosefit.errors import LoosefitInputError
from loosefit.inference.checkpoints import (
    BASELINE_FORMAT,
    MOTION_FORMAT,
    checkpoint_fields,
    load_weights,
    model_config,
    read_checkpoint_file,
    template_from_dict,
)
from loosefit.inference.model_common import (
    arm_collision_of,
    avatar_of,
    body_collider,
    check_motion_joints,
    check_runtime,
)
from loosefit.inference.stages import Stages
from loosefit.inference.stages.collision import CollisionConfig, collision_record
from loosefit.inference.stages.push_out import PushOutHandler
from loosefit.inference.timeline import RolloutConfig
from loosefit.model.baselines import BaselineConfig, BaselineNetwork, baseline_rollout
from loosefit.types import GarmentTemplate, Motion


@dataclass(kw_only=True)
class BaselineModel:
    """A trained baseline, an :class:`~loosefit.inference.protocols.AnimatingModel` as the
    paper's :class:`~loosefit.inference.animator.AnimationModel` is, so that ``loosefit
    animate``/``evaluate`` and the benchmarks run it alike. Built by keyword, or from a
    checkpoint (:meth:`from_checkpoint`).

    ``stages.collision`` runs Santesteban et al.'s post-process (every vertex closer
    to the body than ``collision.epsilon`` pushed out along the body's normal);
    virtual bones have none (Pan et al. have none). There is no detail stage.
    """

    network: BaselineNetwork  # the trained baseline (Santesteban et al., virtual bones)
    template: GarmentTemplate  # the garment it animates
    joint_names: tuple[str, ...]  # the skeleton a motion must be on
    floor_height: float  # the avatar's standing root height
    fps: float  # the frame rate it was trained at
    body: dict  # the avatar's record (its shape)
    rollout_config: RolloutConfig  # the timeline before a motion's first frame
    path: Path  # the checkpoint it came from
    arm_collision: bool | str = False  # the arms in the collider, as the data's simulation
    collision: CollisionConfig = field(default_factory=CollisionConfig)  # epsilon, reach
    stages: Stages = field(default_factory=Stages)  # what animate() runs by default
    detail: None = None  # no detail stage (what the CLI asks of every model)
    _avatar: object = None  # the avatar, built on first use

    @classmethod
    def from_checkpoint(cls, path: str | Path, device="cpu") -> BaselineModel:
        """A trained baseline from a run's ``model.pt`` or ``checkpoint.pt``.

        Raises:
            LoosefitInputError: not a baseline checkpoint, or weights that do not fit the
                configuration it records.
        """
        path = Path(path)
        data = read_checkpoint_file(
            path,
            BASELINE_FORMAT,
            device,
            {
                MOTION_FORMAT: "this is our motion stage; load it with load_pipeline",
            },
        )
        with checkpoint_fields(path, "baseline checkpoint"):
            return _baseline(path, data, device)

    @property
    def method(self) -> str:
        return self.network.method

    @property
    def device(self) -> torch.device:
        return self.network.rest.device

    @property
    def post_process(self) -> bool:
        """Whether the method has a collision post-process (Santesteban's push-out)."""
        return self.method == "santesteban"

    def avatar(self):
        if self._avatar is None:
            self._avatar = avatar_of(self.body)
        return self._avatar

    def check_motion(self, motion: Motion) -> None:
        check_motion_joints(motion, self.joint_names, self.path)

    def animate(
        self,
        motion: Motion,
        progress=None,
        truth=None,
        restart_every=None,
        stages: Stages | None = None,
        runtime: str = "torch",
        collision: str = "full",
    ):
        """The garment through ``motion`` (T, V, 3) world positions, a
        :class:`~loosefit.inference.rollout.RolloutResult`; then the post-process where the
        method has one and ``stages.collision``. ``truth``/``restart_every`` do not
        apply (no previous garment is fed back) and are refused, and so are
        ``runtime="onnx"`` (a baseline runs in PyTorch only) and ``collision="realtime"``
        (its post-process has no rounds to cut)."""
        check_runtime(runtime)
        if collision != "full":
            raise LoosefitInputError(
                self.path,
                "collision",
                f"'full' (the '{self.method}' baseline's own post-process)",
                repr(collision),
            )
        if runtime != "torch":
            raise LoosefitInputError(
                self.path,
                "runtime",
                f"'torch' (a baseline has no ONNX graphs; the '{self.method}' baseline)",
                repr(runtime),
            )
        if restart_every is not None:
            raise LoosefitInputError(
                "BaselineModel.animate",
                "restart_every",
                "None (a baseline never sees the previous garment)",
                restart_every,
            )
        self.check_motion(motion)
        stages = stages or self.stages
        pose = None
        if self.method == "santesteban":
            avatar = self.avatar()
            rot = torch.from_numpy(motion.rotations)
            root = torch.from_numpy(motion.root_translation)

            def pose(s: int, e: int) -> torch.Tensor:
                return avatar.pose(rot[s:e], root[s:e]).joint_transforms

        result = baseline_rollout(
            self.network, motion, self.floor_height, self.rollout_config, pose, progress
        )
        result.stage_seconds = {"motion": result.seconds}
        if stages.collision and self.post_process:
            t0 = time.perf_counter()
            handler = PushOutHandler(
                self.template.faces,
                self.template.num_vertices,
                self.collision.epsilon,
                self.collision.reach,
            )
            arms = True if self.collision.whole_body else self.arm_collision
            collide = body_collider(self.avatar(), handler, motion, arms, self.device)
            result.decoded = result.vertices.copy()
            result.collisions = []
            for t in range(motion.num_frames):
                r = collide(t, torch.from_numpy(result.decoded[t]))
                result.vertices[t] = r.vertices.numpy()
                result.collisions.append(collision_record(r))
            result.stage_seconds["collision"] = time.perf_counter() - t0
            result.seconds += result.stage_seconds["collision"]
        return result


def load_baseline(path: str | Path, device="cpu") -> BaselineModel:
    """:meth:`BaselineModel.from_checkpoint`."""
    return BaselineModel.from_checkpoint(path, device)


def _baseline(path: Path, data: dict, device) -> BaselineModel:
    config = model_config(data)
    template = template_from_dict(data["garment"]["template"])
    V, K = template.num_vertices, int(data["influences"])
    network = BaselineNetwork(
        BaselineConfig(**config["network"]),
        int(data["num_features"]),
        torch.zeros(V, 3),
        torch.zeros(V, K),
    )
    load_weights(network, data["model"], path, "this baseline's configuration")
    return BaselineModel(
        network=network.to(device).eval(),
        template=template,
        joint_names=tuple(data["joint_names"]),
        floor_height=float(data["floor_height"]),
        fps=float(data["fps"]),
        body=dict(data["body"]),
        rollout_config=RolloutConfig(**config["rollout"]),
        path=path,
        arm_collision=arm_collision_of(data),
    )
