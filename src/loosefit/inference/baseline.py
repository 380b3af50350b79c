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
from loosefit.model.baselines import BaselineConfig, BaselineNetwork
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
    def from_checkpoint(
        cls, path: str | Path, device="cpu", data: dict | None = None
    ) -> BaselineModel:
        """A trained baseline from a run's ``model.pt`` or ``checkpoint.pt`` (``data``: its
        contents, when already read).

        Raises:
            LoosefitInputError: not a baseline checkpoint, or weights that do not fit the
                configuration it records.
        """
        path = Path(path)
        hints = {MOTION_FORMAT: "this is our motion stage; open it with loosefit.load"}
        data = read_checkpoint_file(path, BASELINE_FORMAT, device, hints, data=data)
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
        *,
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


@torch.no_grad()
def baseline_rollout(
    network: BaselineNetwork,
    motion,
    floor_height: float,
    config=None,
    pose_joints=None,
    progress=None,
    *,
    chunk: int = 128,
):
    """Animate the garment through a motion with a baseline (no previous garment: the GRU
    runs over the whole timeline at once, then the garment is decoded ``chunk`` frames at
    a time).

    Args:
        network: a trained :class:`BaselineNetwork`.
        motion: T frames on the skeleton it was trained on.
        floor_height: the avatar's standing root height (for the timeline and features).
        config: the preroll (:class:`~loosefit.inference.timeline.RolloutConfig`), as in training.
        pose_joints: Santesteban: ``pose_joints(start, stop) -> (n, J, 4, 4)`` the
            avatar's rest -> world joint transforms of those motion frames.
        progress: called as ``progress(done, total)``.
        chunk: motion frames decoded at once.

    Returns:
        :class:`~loosefit.inference.rollout.RolloutResult`, (T, V, 3) world positions.
    """
    import time

    from loosefit.geometry.skinning import root_frame_transforms
    from loosefit.inference.rollout import RolloutResult, check_garment, timeline
    from loosefit.model.motion_features import (
        feature_joints,
        from_root_frame,
        motion_features,
        root_frames,
    )

    config = config or RolloutConfig()
    network.eval()
    device = network.rest.device
    t0 = time.perf_counter()
    rot, root, P = timeline(motion, floor_height, config)
    joints = feature_joints(motion.joint_names, network.config.joints)
    feats = motion_features(rot, root, motion.fps, floor_height, joints).to(device)
    H, p = (a.float() for a in root_frames(rot[P:].double(), root[P:].double()))
    h, _ = network.encode(feats[None], network.initial_hidden(1, device))
    h = h[0, P:]  # (T, gru): the motion's own frames
    T = motion.num_frames
    out = torch.empty(T, network.num_vertices, 3)
    if network.method == "santesteban" and pose_joints is None:
        raise LoosefitInputError(
            "baseline_rollout",
            "pose_joints",
            "the avatar's joint transforms (Santesteban skins to them)",
            "None",
        )
    for s in range(0, T, chunk):
        e = min(s + chunk, T)
        g = None
        if network.method == "santesteban":
            world = torch.as_tensor(pose_joints(s, e)).float()
            g = root_frame_transforms(world, H[s:e], p[s:e]).to(device)
        local = network.decode(h[s:e], g)["vertices"]
        check_garment(local, config.max_distance, f"motion frames {s}-{e - 1}")
        out[s:e] = from_root_frame(local.cpu(), H[s:e], p[s:e])
        if progress is not None:
            progress(P + e, P + T)
    return RolloutResult(out.numpy(), time.perf_counter() - t0, P + T)


# -- the loss (a pure function) ----------------------------------------------------------
