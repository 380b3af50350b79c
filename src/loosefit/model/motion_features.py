"""Body motion as the dynamic motion encoder sees it (the paper's M_t), and the root frames.

The features of frame ``t`` (``num_features(J) = 6 (J - 1) + 11`` numbers, J
counting the root and the joints the encoder sees):

* the local rotation of every joint the encoder sees but the root (all of
  them, or only :data:`LOWER_BODY_JOINTS`: see :func:`feature_joints`), in the
  continuous 6D form (the first two columns of the matrix, Zhou et al. 2019);
* the root's rotation *relative to its heading* (``H_t^T R_root``): the
  pelvis's tilt and roll, in 6D;
* the root's velocity in the heading frame of ``t`` (m/s): ``H_t^T (p_t -
  p_{t-1}) fps``;
* the heading's turn rate (rad/s, wrapped to (-pi, pi] per frame);
* the root's height above its standing height (m).

Velocities at frame 0 are 0: motions start standing still (the rollout's and
the simulator's preroll blend from the rest pose). None of the features
change when the whole motion is moved on the floor or turned about the
vertical, so the encoder generalises over where the dancer stands and which
way they face; the garment is predicted in the same root frame.

**Root frame.** A garment enters the models in the body's root frame with the
dancer's global translation and heading taken out: ``x_root = H^T (x_world - p)``
where ``p`` is the root joint's world position and ``H`` the rotation about +Z
by the heading (the yaw of the pelvis's forward direction, -Y at rest). The
pelvis's tilt and roll stay in, so the garment still sees the hips bend. The
latent space then spends nothing on where the dancer stands or which way they
face; decoded garments go back with :func:`from_root_frame`.
"""

from __future__ import annotations

import math

import torch

from loosefit.errors import LoosefitInputError

# The joints that move the skin a skirt can touch: the root, the spine up to the
# chest and both legs (CMU names). The arms are not in the simulation's collider
# (``ClothConfig.arm_collision``) and the neck and head are out of a skirt's reach,
# so their rotations carry nothing about the garment; on a small data set they
# are inputs the encoder can only overfit to.
LOWER_BODY_JOINTS: tuple[str, ...] = (
    "Hips", "LowerBack", "Spine", "Spine1",
    "LHipJoint", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase",
    "RHipJoint", "RightUpLeg", "RightLeg", "RightFoot", "RightToeBase",
)  # fmt: skip

# names for the joint sets of ``MotionEncoderConfig.joints``
JOINT_SETS: dict[str, tuple[str, ...] | None] = {"all": None, "lower": LOWER_BODY_JOINTS}


def joint_set(wanted: str) -> tuple[str, ...] | None:
    """The joints of a key of :data:`JOINT_SETS` (None: every joint).

    Raises:
        LoosefitInputError: an unknown set.
    """
    if wanted not in JOINT_SETS:
        raise LoosefitInputError(
            "MotionEncoderConfig", "joints", f"one of {list(JOINT_SETS)}", repr(wanted)
        )
    return JOINT_SETS[wanted]


def feature_joints(joint_names: tuple[str, ...] | list[str], wanted: str) -> list[int]:
    """Indices into ``joint_names`` of the non-root joints whose rotations are features.

    Args:
        joint_names: the skeleton's J joints, the root first.
        wanted: a key of :data:`JOINT_SETS` (``all``: every joint but the root).

    Returns:
        Increasing indices, none of them 0.

    Raises:
        LoosefitInputError: an unknown set, or a skeleton without one of its joints.
    """
    names = joint_set(wanted)
    if names is None:
        return list(range(1, len(joint_names)))
    index = {n: i for i, n in enumerate(joint_names)}
    missing = [n for n in names if n not in index]
    if missing:
        raise LoosefitInputError(
            "motion",
            "joint_names",
            f"the joints of the '{wanted}' set",
            f"a skeleton without {missing}",
        )
    return sorted(index[n] for n in names if index[n] != 0)


def num_features(num_joints: int) -> int:
    """The length F of a frame's features for a skeleton of ``num_joints`` joints."""
    return 6 * (num_joints - 1) + 6 + 3 + 1 + 1


def heading_yaw(root_rotations: torch.Tensor) -> torch.Tensor:
    """(T, 3, 3) root rotations to (T,) yaw about +Z taking -Y (the rest facing) to the facing."""
    forward = -root_rotations[..., :3, 1]
    return torch.atan2(forward[..., 0], -forward[..., 1])


def yaw_matrix(yaw: torch.Tensor) -> torch.Tensor:
    """(T,) angles to (T, 3, 3) rotations about +Z."""
    c, s = torch.cos(yaw), torch.sin(yaw)
    zero, one = torch.zeros_like(c), torch.ones_like(c)
    return torch.stack([c, -s, zero, s, c, zero, zero, zero, one], -1).view(*yaw.shape, 3, 3)


def root_frames(
    rotations: torch.Tensor, root_translation: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """The root frame of every frame: heading H (T, 3, 3) and origin p (T, 3).

    The same frames as :func:`heading_frames` of the root's
    skinning transform, computed from the motion alone.

    Args:
        rotations: (T, J, 3, 3) local joint rotations (joint 0 is the root).
        root_translation: (T, 3) root positions, metres.
    """
    return yaw_matrix(heading_yaw(rotations[:, 0])), root_translation


def _six_d(r: torch.Tensor) -> torch.Tensor:
    """(..., 3, 3) to (..., 6): the first two columns."""
    return torch.cat([r[..., :, 0], r[..., :, 1]], -1)


def frame_features(
    rotations: torch.Tensor,
    root_translation: torch.Tensor,
    previous_root_rotation: torch.Tensor,
    previous_root_translation: torch.Tensor,
    fps: float,
    floor_height: float,
    *,
    joints: list[int] | None = None,
) -> torch.Tensor:
    """The features of B frames from each frame's joints and the root of the frame before
    (see the module's docstring); computed in the inputs' float type.

    A motion's first frame passes its own root as the previous one (no velocity, no turn).
    The ONNX export (:mod:`loosefit.inference.onnx.export`) computes the features so, one
    frame at a time, in its graph.

    Args:
        rotations: (B, J, 3, 3) local joint rotations of the frames.
        root_translation: (B, 3) their root positions, metres.
        previous_root_rotation: (B, 3, 3) the root joint's rotation one frame earlier.
        previous_root_translation: (B, 3) the root position one frame earlier.
        fps: frames per second.
        floor_height: the root's height when the avatar stands.
        joints: indices of the non-root joints whose rotations are features
            (:func:`feature_joints`); by default every joint but the root.

    Returns:
        (B, 6 K + 11) features, K the number of those joints (J - 1 by default).
    """
    B = rotations.shape[0]
    yaw = heading_yaw(rotations[:, 0])
    H = yaw_matrix(yaw)  # (B, 3, 3)
    local = rotations[:, 1:] if joints is None else rotations[:, joints]
    local = _six_d(local).reshape(B, -1)  # (B, 6 K)
    tilt = _six_d(H.transpose(-1, -2) @ rotations[:, 0])  # (B, 6)
    step = root_translation - previous_root_translation
    velocity = (step.unsqueeze(1) @ H).squeeze(1) * fps  # H^T step, as a row vector
    turn = yaw - heading_yaw(previous_root_rotation)
    turn = torch.remainder(turn + math.pi, 2 * math.pi) - math.pi  # wrapped to [-pi, pi)
    height = root_translation[:, 2:] - floor_height
    return torch.cat([local, tilt, velocity, (turn * fps)[:, None], height], -1)


def motion_features(
    rotations: torch.Tensor,
    root_translation: torch.Tensor,
    fps: float,
    floor_height: float,
    joints: list[int] | None = None,
) -> torch.Tensor:
    """The per-frame features of a motion (see the module's docstring): :func:`frame_features`
    of every frame and the one before it, in double precision.

    Args:
        rotations: (T, J, 3, 3) local joint rotations.
        root_translation: (T, 3) root positions, metres.
        fps: frames per second.
        floor_height: the root's height when the avatar stands.
        joints: indices of the non-root joints whose rotations are features
            (:func:`feature_joints`); by default every joint but the root.

    Returns:
        (T, 6 K + 11) float32 features, K the number of those joints (J - 1 by default).
    """
    rotations = rotations.double()
    root = root_translation.double()
    before = torch.cat([rotations[:1, 0], rotations[:-1, 0]])  # (T, 3, 3): frame 0 its own
    root_before = torch.cat([root[:1], root[:-1]])  # (T, 3)
    return frame_features(
        rotations, root, before, root_before, fps, floor_height, joints=joints
    ).float()


def heading_frames(root_transforms: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The heading rotation and origin of the root frame.

    Args:
        root_transforms: (T, 4, 4) the root joint's skinning transform (rest to world).

    Returns:
        H (T, 3, 3), rotations about +Z by the heading, and p (T, 3), the root's position.
    """
    return yaw_matrix(heading_yaw(root_transforms[:, :3, :3])), root_transforms[:, :3, 3]


def motion_root_frames_of(motion) -> tuple[torch.Tensor, torch.Tensor]:
    """:func:`root_frames` of a :class:`~loosefit.types.Motion`'s frames: float32 H (T, 3, 3)
    and p (T, 3), computed in double precision."""
    H, p = root_frames(
        torch.from_numpy(motion.rotations).double(),
        torch.from_numpy(motion.root_translation).double(),
    )
    return H.float(), p.float()


def garment_in_root_frame(motion, garment) -> torch.Tensor:
    """World garments (T, V, 3) of ``motion``'s frames in their root frames (T, V, 3)."""
    H, p = motion_root_frames_of(motion)
    return to_root_frame(torch.as_tensor(garment, dtype=torch.float32), H, p)


def to_root_frame(x: torch.Tensor, H: torch.Tensor, p: torch.Tensor) -> torch.Tensor:
    """World points (T, N, 3) into the root frame of :func:`heading_frames`."""
    return (x - p[:, None]) @ H


def from_root_frame(x: torch.Tensor, H: torch.Tensor, p: torch.Tensor) -> torch.Tensor:
    """Root-frame points (T, N, 3) back into the world."""
    return x @ H.transpose(1, 2) + p[:, None]
