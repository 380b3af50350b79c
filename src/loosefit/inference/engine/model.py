"""The engine tier as a model that animates: its checkpoint, its rollout in PyTorch.

An engine-tier checkpoint (``format`` :data:`ENGINE_FORMAT`, ``engine.pt`` beside a set's
``motion.pt``) holds the network and its basis (:class:`~loosefit.model.engine.EngineTier`)
with everything a rollout needs: the joint names, the frame rate, the floor height, the
timeline of a motion's start, the garment and the body's shape. It names the motion-stage
checkpoint it is the tier of (the settled drape it starts from is that model's).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch

from loosefit.errors import LoosefitInputError
from loosefit.inference.checkpoints import (
    ENGINE_FORMAT,
    checkpoint_fields,
    float_weights,
    load_weights,
    read_checkpoint_file,
    template_from_dict,
)
from loosefit.inference.model_common import check_motion_joints
from loosefit.inference.rollout import RolloutResult, timeline
from loosefit.inference.stages import MOTION_ONLY, Stages
from loosefit.inference.timeline import RolloutConfig
from loosefit.model.engine import EngineConfig, EngineTier, GarmentBasis, correlate_noise
from loosefit.model.motion_features import (
    feature_joints,
    from_root_frame,
    motion_features,
    root_frames,
)
from loosefit.types import GarmentTemplate, Motion

ENGINE_FILE = "engine.pt"  # the engine tier's file beside a set's motion.pt


@dataclass
class EngineModel:
    """A trained engine tier and what its rollout needs.

    Attributes:
        tier: the network and its basis (eval mode).
        template: the garment.
        joint_names: the skeleton's joints, in the order the tier reads them.
        floor_height: the root's height when the avatar stands (m).
        fps: the frame rate it was trained at.
        body: the body record (the avatar's shape) of its data.
        rollout_config: the timeline of a motion's start.
        path: the checkpoint.
        record: what the checkpoint says of its training (data, targets, epochs).
        stages: what runs after the tier: nothing (it has no later stages).
    """

    tier: EngineTier
    template: GarmentTemplate
    joint_names: tuple[str, ...]
    floor_height: float
    fps: float
    body: dict
    rollout_config: RolloutConfig
    path: Path
    record: dict
    stages: Stages = field(default_factory=lambda: MOTION_ONLY)
    detail = None  # no detail stage (what the CLI asks of every model)

    @property
    def joints(self) -> list[int]:
        """The non-root joints whose rotations the features hold."""
        return feature_joints(self.joint_names, self.tier.config.joints)

    def avatar(self):
        from loosefit.inference.model_common import avatar_of

        return avatar_of(self.body)

    def check_motion(self, motion: Motion) -> None:
        """A clear error for a motion on other joints or not finite."""
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
        seed: int = 0,
    ) -> RolloutResult:
        """The tier's garment through ``motion`` (:func:`rollout_engine`), as every model
        that animates (:class:`~loosefit.inference.protocols.AnimatingModel`). The tier has
        no later stages: ``stages`` and ``collision`` change nothing; ``seed``: a stochastic
        tier's realisation.

        Raises:
            LoosefitInputError: a runtime other than PyTorch's (the tier's graph is
                ``loosefit export engine``'s), a drift measurement (``restart_every``), or
                a motion on other joints or at another frame rate.
        """
        if runtime != "torch":
            raise LoosefitInputError(
                self.path,
                "runtime",
                "'torch' (the engine tier runs in PyTorch here; its ONNX graph is "
                "loosefit export engine's)",
                repr(runtime),
            )
        if restart_every is not None:
            raise LoosefitInputError(
                self.path, "restart_every", "None (the engine tier restarts from no truth)", 1
            )
        start = time.perf_counter()
        garments, frames = _rollout(self, motion, None, seed)
        if progress is not None:
            progress(frames, frames)
        return RolloutResult(garments[0], time.perf_counter() - start, frames)


def engine_fields(tier: EngineTier) -> dict:
    """What rebuilds a tier besides its weights: its configuration and sizes."""
    return {
        "model_config": {"engine": asdict(tier.config)},
        "num_features": tier.num_features,
        "num_vertices": tier.num_vertices,
    }


def engine_path_of(motion_checkpoint: str | Path) -> Path:
    """Where a motion-stage checkpoint's engine tier is: ``engine.pt`` beside it."""
    return Path(motion_checkpoint).parent / ENGINE_FILE


def load_engine(path: str | Path, device="cpu", data: dict | None = None) -> EngineModel:
    """A trained engine tier (``data``: the file's contents, when already read).

    Raises:
        LoosefitInputError: not an engine-tier checkpoint, or fields that do not fit.
    """
    path = Path(path)
    data = read_checkpoint_file(path, ENGINE_FORMAT, device, data=data)
    with checkpoint_fields(path, "engine-tier checkpoint"):
        config = EngineConfig(**data["model_config"]["engine"])
        weights = float_weights(data["model"])
        F = int(data["num_features"])
        # a tier saved before its features' range was recorded reads them unclamped
        weights.setdefault("feature_low", torch.full((F,), -float("inf")))
        weights.setdefault("feature_high", torch.full((F,), float("inf")))
        K, V = config.basis, int(data["num_vertices"])
        empty = GarmentBasis(torch.zeros(V, 3), torch.zeros(K, V, 3), torch.ones(K), torch.ones(K))
        tier = EngineTier(F, config, empty)
        load_weights(tier, weights, path, "this engine-tier configuration")
        template = template_from_dict(data["garment"]["template"])
        return EngineModel(
            tier=tier.to(device).eval(),
            template=template,
            joint_names=tuple(data["joint_names"]),
            floor_height=float(data["floor_height"]),
            fps=float(data["fps"]),
            body=dict(data["body"]),
            rollout_config=RolloutConfig(**data["model_config"]["rollout"]),
            path=path,
            record=dict(data.get("record", {})),
        )


@torch.no_grad()
def engine_noise(tier: EngineTier, frames: int, seed: int) -> torch.Tensor | None:
    """(frames, N) a stochastic tier's noise for one rollout, drawn from ``seed`` on the CPU
    (the same draws on every machine), correlated in time as the tier was trained
    (:func:`~loosefit.model.engine.correlate_noise`); None for a deterministic tier."""
    if not tier.config.noise:
        return None
    gen = torch.Generator().manual_seed(int(seed))
    white = torch.randn(frames, tier.config.noise, generator=gen)
    return correlate_noise(white, float(tier.config.noise_correlation))


@torch.no_grad()
def rollout_engine(
    model: EngineModel, motion: Motion, coefficients: bool = False, collide=None, seed: int = 0
):
    """The engine tier's garment through ``motion``, in PyTorch: the rest pose, the blend
    into the motion (as every loosefit rollout), then one step per frame.

    Args:
        model: the tier.
        motion: T frames on its joints, at its frame rate.
        coefficients: also return the coefficients of the motion's frames.
        collide: an :class:`~loosefit.inference.engine.export.EngineStep` with capsules:
            its push-out applied to the garments (the exported graph's ``garment``).
        seed: a stochastic tier's realisation (:func:`engine_noise`); a deterministic tier
            has one.

    Returns:
        (T, V, 3) float32 world garments (and (T, K) coefficients with ``coefficients``).

    Raises:
        LoosefitInputError: a motion on other joints or at another frame rate.
    """
    (garments, out), _ = _rollout(model, motion, collide, seed)
    return (garments, out) if coefficients else garments


@torch.no_grad()
def _rollout(model: EngineModel, motion: Motion, collide, seed: int):
    """:func:`rollout_engine`'s ((T, V, 3) garments, (T, K) coefficients), and the frames
    computed (P + T)."""
    check_motion_joints(motion, model.joint_names, model.path)
    if abs(motion.fps - model.fps) > 1e-6:
        raise LoosefitInputError(
            f"motion '{motion.name}'", "fps", f"{model.fps:g}", f"{motion.fps:g}", hint="resample"
        )
    tier = model.tier
    device = tier.mean.device
    rot, root, P = timeline(motion, model.floor_height, model.rollout_config)
    feats = motion_features(rot, root, model.fps, model.floor_height, model.joints).to(device)
    H, p = (a.float().to(device) for a in root_frames(rot.double(), root.double()))
    hidden, c = tier.initial_hidden(1, device), tier.initial_coefficients(1)
    out = torch.empty(len(rot) - P, tier.config.basis, device=device)
    noise = engine_noise(tier, len(rot), seed)
    for t in range(len(rot)):
        z = None if noise is None else noise[t : t + 1].to(device)
        c, hidden = tier(feats[t : t + 1], c, hidden, z)
        if t >= P:
            out[t - P] = c[0]
    garments = from_root_frame(tier.decode(out), H[P:], p[P:])
    if collide is not None:
        from loosefit.geometry.capsule import chain_frames, push_out

        r, q = (torch.from_numpy(a[P:]).float().to(device) for a in (rot.numpy(), root.numpy()))
        R, o = chain_frames(r, q, collide.parents, collide.offsets, collide.capsule_joints)
        a = (R @ collide.capsule_start[..., None])[..., 0] + o
        b = (R @ collide.capsule_end[..., None])[..., 0] + o
        garments = push_out(garments, a, b, collide.radius, q, collide.push_weight)
    return (garments.cpu().numpy(), out.cpu().numpy()), len(rot)


def rest_coefficients(tier: EngineTier, rest: np.ndarray | torch.Tensor) -> torch.Tensor:
    """(K,) the coefficients of a settled drape (V, 3) in the rest pose's root frame."""
    from loosefit.model.engine import project

    mean = tier.mean
    basis = tier.basis.view(-1, tier.num_vertices, 3)
    return project(torch.as_tensor(rest, dtype=torch.float32), mean, basis)
