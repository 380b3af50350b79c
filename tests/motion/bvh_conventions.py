"""BVH files in other tools' conventions, written from a motion on the avatar.

:func:`write_convention_bvh` writes a motion as a BVH whose skeleton is the
avatar's (or a subset of it), renamed to a convention (Mixamo, Unreal, SMPL, a
studio layout...), posed at rest as that convention is (a T-pose, an A-pose,
arms down), in its units and with its channels, such that retargeting it back
must give the motion again: each limb's rest pose is the avatar's carried by the
smallest rotation onto the convention's bone direction (what retargeting undoes),
and the joints a convention lacks hold still in the motion (:func:`reduced`).

A convention with ``bone_axis`` set writes a rig whose zero pose does not stand: each
joint's frame is turned (a constant "joint orient" per joint, twisted about the bone
too) so that its bone lies along its own local axis, e.g. ``"x"``: the spine along
+X, the left leg along +X, the right leg along -X (the right side's bones along the
negative axis); the standing orientation is carried by every frame's rotations, as
game and studio rigs write it. Retargeting cannot lean on the zero pose there.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from loosefit.body.avatar import Skeleton
from loosefit.geometry.rotations import rotation_between
from loosefit.motion.joint_maps import LIMBS
from loosefit.motion.retarget import axis_change
from loosefit.types import Motion

OUT, DOWN, FWD = np.array([1.0, 0, 0]), np.array([0, 0, -1.0]), np.array([0, -1.0, 0])


def _sided(
    template: dict[str, str], sides=(("Left", "L", "l", "left"), ("Right", "R", "r", "right"))
) -> dict:
    """{avatar: source} with {S}/{s}/{x}/{w} placeholders for Left/L, L/R, l/r, left/right."""
    out = {}
    for a, b in template.items():
        if "{" not in a:
            out[a] = b
            continue
        for S, s, x, w in sides:
            out[a.format(S=S, s=s)] = b.format(S=S, s=s, x=x, w=w)
    return out


def tpose(sign: float) -> dict[str, np.ndarray]:
    """Limb directions of a T-pose for one side (sign +1 left, -1 right), avatar axes."""
    out = OUT * [sign, 1, 1]
    return {
        "Shoulder": out,
        "Arm": out,
        "ForeArm": out,
        "Hand": out,
        "UpLeg": DOWN,
        "Leg": DOWN,
        "Foot": np.array([0, -0.5, -1.0]),
        "ToeBase": FWD,
    }


def apose(sign: float) -> dict[str, np.ndarray]:
    """An A-pose: arms 45 degrees down, legs a little apart."""
    d = np.array([sign, 0, -1.0])
    return {
        "Shoulder": OUT * [sign, 1, 1],
        "Arm": d,
        "ForeArm": d,
        "Hand": d,
        "UpLeg": np.array([0.1 * sign, 0, -1]),
        "Leg": DOWN,
        "Foot": np.array([0, -1, -1.0]),
        "ToeBase": FWD,
    }


def arms_down(sign: float) -> dict[str, np.ndarray]:
    """Arms hanging along the sides, feet flat: bones along -Z, +-X and -Y."""
    return {
        "Shoulder": OUT * [sign, 1, 1],
        "Arm": DOWN,
        "ForeArm": DOWN,
        "Hand": DOWN,
        "UpLeg": DOWN,
        "Leg": DOWN,
        "Foot": FWD,
        "ToeBase": FWD,
    }


@dataclass
class Convention:
    """A naming and rest-pose convention for a humanoid BVH.

    Attributes:
        name: a label.
        joints: avatar joint -> the convention's name, the joints it has.
        pose: side sign -> limb directions at rest (``tpose``, ``apose``, ``arms_down``).
        extras: joints the avatar lacks: (name, parent's name or None for a new BVH root
            above the hips, avatar joint whose bone (head to tail) gives the offset).
        units: file units per metre.
        six_channels: position and rotation channels on every joint.
        order: rotation channel order.
        up, forward: the file's up axis and the way the skeleton faces at rest.
        bone_axis: None (the zero pose is the standing rest ``pose``), or "x"/"y": each
            bone along its joint's own local axis at zero pose (see the module).
        orient_twist: degrees the joint orients turn each joint about its bone, times
            the joint's index (0: the smallest turn onto the axis).
        start: (3,) metres, avatar axes: where the capture started, baked into the hips'
            OFFSET below a root joint of no geometry of its own at the origin (studio
            exports); None: the hips sit above that root at their height.
        zero_offsets: every OFFSET and End Site written as zeros, each joint's bone in its
            position channels (the skeleton's shape exists only in the frames).
    """

    name: str
    joints: dict[str, str]
    pose: object = tpose
    extras: list[tuple[str, str | None, str | None]] = field(default_factory=list)
    units: float = 1.0
    six_channels: bool = False
    order: str = "ZXY"
    up: str = "+y"
    forward: str = "+z"
    bone_axis: str | None = None
    orient_twist: float = 0.0
    start: tuple[float, float, float] | None = None
    zero_offsets: bool = False


CMU_MB = Convention(
    "cmu_mb",
    {
        n: n
        for n in (
            "Hips LHipJoint LeftUpLeg LeftLeg LeftFoot LeftToeBase LowerBack Spine Spine1 "
            "LeftShoulder LeftArm LeftForeArm LeftHand LThumb LeftFingerBase LeftHandFinger1 "
            "Neck Neck1 Head RightShoulder RightArm RightForeArm RightHand RThumb "
            "RightFingerBase RightHandFinger1 RHipJoint RightUpLeg RightLeg RightFoot "
            "RightToeBase"
        ).split()
    },
    order="ZYX",
)
DAZ = Convention(
    "daz",
    _sided(
        {
            "Hips": "hip",
            "LowerBack": "abdomen",
            "Spine1": "chest",
            "Neck": "neck",
            "Head": "head",
            "{s}HipJoint": "{x}Buttock",
            "{S}UpLeg": "{x}Thigh",
            "{S}Leg": "{x}Shin",
            "{S}Foot": "{x}Foot",
            "{S}Shoulder": "{x}Collar",
            "{S}Arm": "{x}Shldr",
            "{S}ForeArm": "{x}ForeArm",
            "{S}Hand": "{x}Hand",
        }
    ),
    units=100,
)
MIXAMO = Convention(
    "mixamo",
    _sided(
        {
            "Hips": "mixamorig:Hips",
            "LowerBack": "mixamorig:Spine",
            "Spine": "mixamorig:Spine1",
            "Spine1": "mixamorig:Spine2",
            "Neck": "mixamorig:Neck",
            "Head": "mixamorig:Head",
            **{
                f"{{S}}{b}": f"mixamorig:{{S}}{b}"
                for b in ("UpLeg", "Leg", "Foot", "ToeBase", "Shoulder", "Arm", "ForeArm", "Hand")
            },
        }
    ),
    extras=[
        ("mixamorig:HeadTop_End", "mixamorig:Head", "Head"),
        ("mixamorig:LeftHandIndex1", "mixamorig:LeftHand", "LeftHand"),
        ("mixamorig:RightHandIndex1", "mixamorig:RightHand", "RightHand"),
        ("mixamorig:LeftToe_End", "mixamorig:LeftToeBase", "LeftToeBase"),
        ("mixamorig:RightToe_End", "mixamorig:RightToeBase", "RightToeBase"),
    ],
    units=100,
    order="XYZ",
)
UNREAL = Convention(
    "unreal",
    _sided(
        {
            "Hips": "pelvis",
            "LowerBack": "spine_01",
            "Spine": "spine_02",
            "Spine1": "spine_03",
            "Neck": "neck_01",
            "Head": "head",
            "{S}Shoulder": "clavicle_{x}",
            "{S}Arm": "upperarm_{x}",
            "{S}ForeArm": "lowerarm_{x}",
            "{S}Hand": "hand_{x}",
            "{S}UpLeg": "thigh_{x}",
            "{S}Leg": "calf_{x}",
            "{S}Foot": "foot_{x}",
            "{S}ToeBase": "ball_{x}",
        }
    ),
    pose=apose,
    units=100,
)
STUDIO = Convention(
    "studio",
    _sided(
        {
            "Hips": "Hips",
            "LowerBack": "Spine",
            "Spine1": "Chest",
            "Neck": "Neck",
            "Head": "Head",
            "{S}Shoulder": "Shoulder_{s}",
            "{S}Arm": "UpperArm_{s}",
            "{S}ForeArm": "LowerArm_{s}",
            "{S}Hand": "Hand_{s}",
            "{S}UpLeg": "UpperLeg_{s}",
            "{S}Leg": "LowerLeg_{s}",
            "{S}Foot": "Foot_{s}",
            "{S}ToeBase": "Toes_{s}",
        }
    ),
    pose=arms_down,
    extras=[("joint_Root", None, None)],
    units=100,
    six_channels=True,
    order="YXZ",
)
SMPL = Convention(
    "smpl",
    _sided(
        {
            "Hips": "pelvis",
            "{S}UpLeg": "{w}_hip",
            "{S}Leg": "{w}_knee",
            "{S}Foot": "{w}_ankle",
            "{S}ToeBase": "{w}_foot",
            "LowerBack": "spine1",
            "Spine": "spine2",
            "Spine1": "spine3",
            "Neck": "neck",
            "Head": "head",
            "{S}Shoulder": "{w}_collar",
            "{S}Arm": "{w}_shoulder",
            "{S}ForeArm": "{w}_elbow",
            "{S}Hand": "{w}_wrist",
        }
    ),
    extras=[("left_hand", "left_wrist", "LeftHand"), ("right_hand", "right_wrist", "RightHand")],
)
# No names to go by: everything from the structure (sides from the rest pose).
NAMELESS = Convention(
    "nameless",
    {
        n: f"node{i:02d}"
        for i, n in enumerate(
            "Hips LHipJoint LeftUpLeg LeftLeg LeftFoot LeftToeBase LowerBack Spine Spine1 "
            "LeftShoulder LeftArm LeftForeArm LeftHand Neck Neck1 Head RightShoulder RightArm "
            "RightForeArm RightHand RHipJoint RightUpLeg RightLeg RightFoot "
            "RightToeBase".split()
        )
    },
    units=100,
)

CONVENTIONS = {c.name: c for c in (CMU_MB, DAZ, MIXAMO, UNREAL, STUDIO, SMPL, NAMELESS)}

# The studio rig as game and studio exporters write it: every bone along its joint's
# local X axis at zero pose (the left leg along +X, the right leg along -X), joint
# orients twisted about the bones, the standing orientation in every frame.
STUDIO_X = Convention(
    "studio-x",
    STUDIO.joints,
    pose=tpose,
    extras=STUDIO.extras,
    units=100,
    six_channels=True,
    order="ZXY",
    bone_axis="x",
    orient_twist=37.0,
)


def reduced(motion: Motion, keep) -> Motion:
    """The motion with every joint not in ``keep`` held at its rest (identity) rotation."""
    rot = motion.rotations.copy()
    for j, n in enumerate(motion.joint_names):
        if n not in keep:
            rot[:, j] = np.eye(3)
    return Motion(motion.joint_names, rot, motion.root_translation, motion.fps, motion.name)


def joint_positions(skeleton: Skeleton, motion: Motion) -> np.ndarray:
    """(T, J, 3) avatar joint positions: the root at its translation, bones rotated."""
    T, J = motion.rotations.shape[:2]
    world = np.zeros((T, J, 3, 3))
    pos = np.zeros((T, J, 3))
    for j, p in enumerate(skeleton.parents):
        rot = motion.rotations[:, j].astype(np.float64)
        if p < 0:
            world[:, j], pos[:, j] = rot, motion.root_translation
        else:
            world[:, j] = world[:, p] @ rot
            pos[:, j] = pos[:, p] + world[:, p] @ (skeleton.heads[j] - skeleton.heads[p])
    return pos


def world_rotations(skeleton: Skeleton, motion: Motion) -> np.ndarray:
    """(T, J, 3, 3) world rotations of the avatar's joints in a motion."""
    T, J = motion.rotations.shape[:2]
    world = np.zeros((T, J, 3, 3))
    for j, p in enumerate(skeleton.parents):
        rot = motion.rotations[:, j].astype(np.float64)
        world[:, j] = rot if p < 0 else world[:, p] @ rot
    return world


def write_convention_bvh(
    path: Path, conv: Convention, skeleton: Skeleton, motion: Motion, floor_height: float
) -> Path:
    """Write ``reduced(motion, conv.joints)`` as a BVH in the convention; returns ``path``."""
    C = axis_change(conv.up, conv.forward).astype(np.float64)  # file axes -> avatar axes
    names, parents = skeleton.names, skeleton.parents
    heads, tails = skeleton.heads.astype(np.float64), skeleton.tails.astype(np.float64)
    kept = [a for a in names if a in conv.joints]
    src_parent = {}  # avatar joint -> nearest kept avatar ancestor
    for a in kept:
        p = parents[names.index(a)]
        while p >= 0 and names[p] not in conv.joints:
            p = parents[p]
        src_parent[a] = names[p] if p >= 0 else None
    extra_kids = {p for _, p, _ in conv.extras if p}
    has_children = {src_parent[a] for a in kept if src_parent[a]} | {
        a for a in kept if conv.joints[a] in extra_kids
    }

    # 1. Rest alignment of each avatar bone, as retargeting will measure it.
    J = len(names)
    A = np.tile(np.eye(3), (J, 1, 1))
    for a, an in enumerate(names):
        p = parents[a]
        A[a] = A[p] if p >= 0 else np.eye(3)
        if an not in LIMBS or an not in conv.joints:
            continue
        kids = [c for c in skeleton.children(a) if names[c] in conv.joints]
        if kids:
            c = min(kids, key=lambda c: np.linalg.norm(heads[c] - tails[a]))
            d_av = heads[c] - heads[a]
        elif an not in has_children:  # a leaf: an End Site along the avatar's bone
            d_av = tails[a] - heads[a]
        else:
            continue
        sign = 1.0 if an.startswith("Left") else -1.0
        target = conv.pose(sign)[an.removeprefix("Left").removeprefix("Right")]
        A[a] = rotation_between(d_av[None], target[None])[0].astype(np.float64)
    rest = np.zeros((J, 3))  # the convention's rest pose, avatar axes
    for j, p in enumerate(parents):
        if p >= 0:
            rest[j] = rest[p] + A[p] @ (heads[j] - heads[p])

    # 2. World rotations of the source joints, then local ones.
    ref = reduced(motion, conv.joints)
    W = world_rotations(skeleton, ref)  # (T, J, 3, 3)
    Q = {a: C.T @ W[:, names.index(a)] @ A[names.index(a)].T @ C for a in kept}
    T = motion.num_frames
    u = conv.units

    # 2b. Joint orients (file axes): O[a] turns the joint's frame so that its bone lies
    # along its own local axis; offsets are then written in the turned frames.
    O = {a: np.eye(3) for a in kept}
    if conv.bone_axis is not None:
        axis = np.eye(3)["xyz".index(conv.bone_axis)]
        for i, a in enumerate(kept):
            j = names.index(a)
            kids = [c for c in kept if src_parent[c] == a]
            if kids:
                c = min(kids, key=lambda c: np.linalg.norm(heads[names.index(c)] - tails[j]))
                d = C.T @ (rest[names.index(c)] - rest[j])
            else:  # an End Site or an extra joint along the avatar's bone
                d = C.T @ A[j] @ (tails[j] - heads[j])
            sign = -1.0 if a.startswith(("Right", "RHip")) else 1.0
            R0 = rotation_between((sign * axis)[None], d[None])[0].astype(np.float64)
            O[a] = (
                Rotation.from_rotvec(
                    np.radians(conv.orient_twist * i) * d / np.linalg.norm(d)
                ).as_matrix()
                @ R0
            )
    Ot = {a: O[a].T for a in kept}
    local = {
        a: Q[a] @ O[a]
        if src_parent[a] is None
        else Ot[src_parent[a]] @ np.swapaxes(Q[src_parent[a]], -1, -2) @ Q[a] @ O[a]
        for a in kept
    }

    # 3. The hierarchy: (name, offset in file units, End Site or None, frame values).
    def to_file(v):
        return (C.T @ v) * u

    def in_frame(a, v):  # a file-axes vector in joint a's turned frame
        return Ot[a] @ v if a is not None else v

    root_extra = next((e for e in conv.extras if e[1] is None), None)
    hips_pos = to_file(ref.root_translation.astype(np.float64).T).T  # (T, 3)
    children: dict[str | None, list[str]] = {}
    for a in kept:
        children.setdefault(src_parent[a], []).append(a)
    lines = ["HIERARCHY"]
    columns: list[np.ndarray] = []
    euler = conv.order

    def channels(position: bool) -> str:
        rot = " ".join(f"{c}rotation" for c in euler)
        return (
            f"CHANNELS 6 Xposition Yposition Zposition {rot}" if position else f"CHANNELS 3 {rot}"
        )

    def emit(name, offset, rotations, positions, end, kids_fn, depth, keyword="JOINT"):
        pad = "  " * depth
        if conv.zero_offsets:  # the bone lives in the position channels alone
            offset = np.zeros(3)
            end = None if end is None else np.zeros(3)
        lines.append(f"{pad}{keyword} {name}")
        lines.append(f"{pad}{{")
        lines.append(f"{pad}  OFFSET {' '.join(f'{v:.6f}' for v in offset)}")
        lines.append(f"{pad}  {channels(positions is not None)}")
        if positions is not None:
            columns.append(positions)
        angles = Rotation.from_matrix(rotations).as_euler(euler.upper(), degrees=True)
        columns.append(angles)
        kids_fn(depth + 1)
        if end is not None:
            lines.append(f"{pad}  End Site")
            lines.append(f"{pad}  {{")
            lines.append(f"{pad}    OFFSET {' '.join(f'{v:.6f}' for v in end)}")
            lines.append(f"{pad}  }}")
        lines.append(f"{pad}}}")

    eye = np.broadcast_to(np.eye(3), (T, 3, 3))

    def emit_avatar(a, depth, keyword="JOINT"):
        j = names.index(a)
        q = src_parent[a]
        offset = in_frame(q, to_file(rest[j] - rest[names.index(q)])) if q else np.zeros(3)
        if a == "Hips" and root_extra:
            offset = to_file(np.array([0, 0, floor_height]) + (conv.start or 0.0))
        positions = None
        if a == "Hips":
            positions = hips_pos + offset if conv.zero_offsets else hips_pos
        elif conv.six_channels or conv.zero_offsets:
            positions = np.broadcast_to(offset, (T, 3))  # studio files repeat the offset
        mine = [e for e in conv.extras if e[1] == conv.joints[a]]
        leaf = a not in has_children
        end = in_frame(a, to_file(A[j] @ (tails[j] - heads[j]))) if leaf else None

        def kids_fn(d):
            for c in children.get(a, []):
                emit_avatar(c, d)
            for name, _, bone in mine:
                b = names.index(bone)
                off = in_frame(a, to_file(A[b] @ (tails[b] - heads[b])))
                six = conv.six_channels or conv.zero_offsets
                pos = np.broadcast_to(off, (T, 3)) if six else None
                emit(name, off, eye, pos, off * 0.5, lambda d: None, d)

        emit(conv.joints[a], offset, local[a], positions, end, kids_fn, depth, keyword)

    if root_extra:
        emit(
            root_extra[0],
            np.zeros(3),
            eye,
            np.zeros((T, 3)),
            None,
            lambda d: emit_avatar("Hips", d),
            0,
            "ROOT",
        )
    else:
        emit_avatar("Hips", 0, "ROOT")
    data = np.concatenate([np.asarray(c).reshape(T, -1) for c in columns], axis=1)  # (T, C)
    lines += ["MOTION", f"Frames: {T}", f"Frame Time: {1.0 / motion.fps!r}"]
    lines += [" ".join(f"{v:.6f}" for v in row) for row in data]
    path.write_text("\n".join(lines) + "\n")
    return path


def motion_error(avatar, want, got, joints) -> tuple[float, float]:
    """Mean and max distance (m) of the mapped joints of ``got`` from ``want`` (reduced to
    ``joints``), after the one constant shift that recentring and grounding add."""
    idx = [avatar.skeleton.names.index(a) for a in joints]
    ref = reduced(want, joints)
    d = (
        joint_positions(avatar.skeleton, got)[:, idx]
        - joint_positions(avatar.skeleton, ref)[:, idx]
    )
    d -= d.reshape(-1, 3).mean(0)
    err = np.linalg.norm(d, axis=-1)
    return float(err.mean()), float(err.max())


# Studio exports as a whole data set writes them: the capture's start position baked
# into the hips' OFFSET, metres from a root joint of no geometry at the origin.
STUDIO_FAR = dataclasses.replace(STUDIO_X, name="studio-far", start=(6.5, -4.0, 0.0))
# No OFFSETs at all: every joint's bone in its position channels, the shape in the frames.
STUDIO_ZERO = dataclasses.replace(STUDIO_FAR, name="studio-zero", zero_offsets=True)
MIXAMO_ZERO = dataclasses.replace(MIXAMO, name="mixamo-zero", zero_offsets=True)
# Every rig convention the retargeting is held to: the named ones, and the studio rigs.
ALL_CONVENTIONS = {
    c.name: c for c in (*CONVENTIONS.values(), STUDIO_X, STUDIO_FAR, STUDIO_ZERO, MIXAMO_ZERO)
}
