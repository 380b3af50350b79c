"""What both kinds of trained model share: the runtime and motion checks, the avatar of a
checkpoint, and the body collider along a motion."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from loosefit.errors import LoosefitInputError
from loosefit.inference.stages.collision import BodyCollider
from loosefit.types import Motion

RUNTIMES = ("torch", "onnx")  # what runs the learned stages: PyTorch, or onnxruntime


def check_runtime(runtime: str, source: str = "animate") -> None:
    """A clear error for a runtime other than :data:`RUNTIMES`."""
    if runtime not in RUNTIMES:
        raise LoosefitInputError(source, "runtime", " or ".join(map(repr, RUNTIMES)), repr(runtime))


def check_motion_joints(motion: Motion, joint_names: tuple[str, ...], path: Path) -> None:
    """A clear error for a motion on other joints than a checkpoint's, or not finite."""
    if tuple(motion.joint_names) != tuple(joint_names):
        missing = [j for j in joint_names if j not in motion.joint_names]
        raise LoosefitInputError(
            f"motion '{motion.name}'",
            "joint_names",
            f"the {len(joint_names)} joints the checkpoint {Path(path).name} was "
            "trained on, in its order",
            f"{len(motion.joint_names)} joints"
            + (f", missing {missing[:5]}" if missing else ", in another order"),
        )
    if not np.isfinite(motion.rotations).all() or not np.isfinite(motion.root_translation).all():
        raise LoosefitInputError(
            f"motion '{motion.name}'",
            "rotations/root_translation",
            "finite numbers",
            "NaN or infinity",
        )


def body_collider(
    avatar, handler, motion: Motion, arm_collision: bool | str, device: torch.device
) -> BodyCollider:
    """``handler`` (Eq. 16's, or a baseline's push-out) along ``motion``'s posed body, the
    simulation's collider (the arms in it only with ``arm_collision``)."""
    rot = torch.from_numpy(motion.rotations)
    root = torch.from_numpy(motion.root_translation)

    def pose(start: int, stop: int) -> np.ndarray:
        return avatar.pose(rot[start:stop], root[start:stop]).vertices.cpu().numpy()

    faces = avatar.collider_faces(arms=arm_collision).cpu().numpy()
    warp_device = "cpu" if device.type == "cpu" else f"cuda:{device.index or 0}"
    return BodyCollider(handler, faces, pose, motion.num_frames, device=warp_device)


def avatar_of(body: dict):
    """The avatar of a checkpoint's ``body`` record (its shape)."""
    from loosefit.body.avatar import Avatar, AvatarConfig

    return Avatar(AvatarConfig(shape=dict(body.get("shape", {}))))


def arm_collision_of(data: dict, default: bool | str = False) -> bool | str:
    """The arms the cloth met as the data was simulated: False, True or "upper" (True also
    where they were a collider of their own, ``ClothConfig.arm_friction``; data made before
    that field existed had none); ``default`` where the configuration does not say."""
    cloth = data.get("cloth") or {}
    if cloth.get("arm_friction") is not None:
        return True
    arms = cloth.get("arm_collision", default)
    return arms if arms == "upper" else bool(arms)
