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

The clip's skeleton is a fixed template, :data:`SMPL_OFFSETS`: the rest joints of
SMPL's neutral model at mean shape (betas = 0), in SMPL's body frame (x to the
body's left, y up, z forward, metres), the numbers that physics-based SMPL
humanoids publish (e.g. ProtoMotions' and PHC's ``smpl_humanoid.xml``), rounded to
0.1 mm. Its arms are nearly level (SMPL's rest is a T-pose), its legs 0.78 m from
hip to ankle: a dancer of about 1.6 m by the retargeting's measure. The shape
parameters (``betas``) are not read: the retargeting carries rotations, and scales
the root's path by leg length.

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

from loosefit.body.bvh import BvhClip
from loosefit.body.joint_maps import AXES
from loosefit.body.rotations import axis_angle_to_matrix, rotation_between
from loosefit.errors import LoosefitInputError

SMPL_JOINTS = (
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2",
    "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot", "neck",
    "left_collar", "right_collar", "head", "left_shoulder", "right_shoulder",
    "left_elbow", "right_elbow", "left_wrist", "right_wrist",
)  # fmt: skip
SMPL_PARENTS = (-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19)

# (22, 3) rest offset of each body joint from its parent (the pelvis: its rest position),
# SMPL neutral at mean shape, metres, SMPL's body frame (x left, y up, z forward).
SMPL_OFFSETS = np.array([
    [-0.0018, -0.2233, 0.0282],   # pelvis
    [0.0695, -0.0914, -0.0068],   # left_hip
    [-0.0677, -0.0905, -0.0043],  # right_hip
    [-0.0025, 0.1090, -0.0267],   # spine1
    [0.0343, -0.3752, -0.0045],   # left_knee
    [-0.0383, -0.3826, -0.0089],  # right_knee
    [0.0055, 0.1352, 0.0011],     # spine2
    [-0.0136, -0.3980, -0.0437],  # left_ankle
    [0.0158, -0.3984, -0.0423],   # right_ankle
    [0.0015, 0.0529, 0.0254],     # spine3
    [0.0264, -0.0558, 0.1193],    # left_foot (the ball of the foot)
    [-0.0254, -0.0481, 0.1233],   # right_foot
    [-0.0028, 0.2139, -0.0429],   # neck
    [0.0788, 0.1217, -0.0341],    # left_collar
    [-0.0818, 0.1188, -0.0386],   # right_collar
    [0.0052, 0.0650, 0.0513],     # head
    [0.0910, 0.0305, -0.0089],    # left_shoulder
    [-0.0960, 0.0326, -0.0091],   # right_shoulder
    [0.2596, -0.0128, -0.0275],   # left_elbow
    [-0.2537, -0.0133, -0.0214],  # right_elbow
    [0.2492, 0.0090, -0.0012],    # left_wrist
    [-0.2553, 0.0078, -0.0056],   # right_wrist
])  # fmt: skip
# End Sites: the hands (SMPL's joints 22 and 23, from the wrists) and the toe tips
# (5 cm forward along the ground from the balls of the feet; SMPL has no toe tip).
SMPL_END_OFFSETS = {
    20: np.array([0.0840, -0.0082, -0.0149]),
    21: np.array([-0.0846, -0.0061, -0.0103]),
    10: np.array([0.0108, 0.0, 0.0488]),
    11: np.array([-0.0100, 0.0, 0.0490]),
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
                "joints read, on SMPL's mean-shape skeleton)",
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
            path, name, "finite values",
            f"{a[tuple(where)]} at frame {where[0]}"
            + (f", column {where[1]}" if len(where) > 1 else "")
            + f" ({int(bad.sum())} in all)",
        )  # fmt: skip


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
            raise LoosefitInputError(path, name, f"a '{name}' array (an SMPL pose file)",
                                     f"fields {sorted(fields)}")  # fmt: skip
    rate_key = next((k for k in FRAME_RATE_KEYS if k in fields), None)
    if rate_key is None:
        raise LoosefitInputError(
            path, "mocap_framerate", f"a frame rate: one of {list(FRAME_RATE_KEYS)}",
            f"none (fields {sorted(fields)})",
            hint="add one, e.g. np.savez(..., mocap_framerate=120)",
        )  # fmt: skip
    with np.load(path, allow_pickle=False) as z:
        poses, trans, rate = (_field(z, path, k) for k in ("poses", "trans", rate_key))
    if poses.ndim == 3 and poses.shape[2] == 3:  # (T, K, 3)
        poses = poses.reshape(len(poses), -1)
    if poses.ndim != 2 or poses.shape[1] not in POSE_WIDTHS or len(poses) < 1:
        raise LoosefitInputError(
            path, "poses", f"shape (T, {' | '.join(map(str, POSE_WIDTHS))}) (SMPL, SMPL-H, "
            "SMPL-X axis-angles)", f"{poses.shape}",
        )  # fmt: skip
    T = len(poses)
    if trans.shape != (T, 3):
        raise LoosefitInputError(path, "trans", f"shape ({T}, 3) (one per frame of poses)",
                                 f"{trans.shape}")  # fmt: skip
    if rate.size != 1 or not np.isfinite(rate.ravel()[0]) or rate.ravel()[0] <= 0:
        raise LoosefitInputError(path, rate_key, "a positive frame rate", f"{rate.ravel()[:3]}")
    _finite(path, "poses", poses)
    _finite(path, "trans", trans)
    return smpl_clip(poses, trans, float(rate.ravel()[0]), up, path)
