"""Retargeting motion capture to the avatar's skeleton by joint names.

The method copies each mapped source joint's *world* rotation, measured from
the source's zero pose, onto the avatar bone it maps to:

    G_a(t) = C Q_b(t) C^T  A_a

where ``Q_b(t)`` is the source joint's world rotation at frame t (identity at
the BVH zero pose, normally a T-pose), ``C`` turns the source's axes into the
avatar's (Z up, facing -Y), and ``A_a`` is the **rest-pose alignment**: the
world rotation that carries the avatar bone from its own rest pose (anny's
A-pose) to the pose of the source skeleton at zero rotation. For limbs (listed
in the joint map's ``align``), ``A_a`` is the smallest rotation taking the
avatar bone's direction onto the source bone's direction at rest, so a T-pose
capture gives the avatar's T-pose; other bones (spine, neck, head) keep
``A_a = A_parent``: the two skeletons are taken to stand alike there, and the
avatar keeps its own posture. Unmapped avatar joints follow their parent
rigidly. Local rotations are then ``R_a = G_parent^T G_a``.

The root translation is the source root's position scaled by the ratio of the
two skeletons' leg lengths, recentred to start at the origin in XY, and shifted
in Z so the feet rest on the floor.

Which source joint drives each avatar joint (:func:`resolve_joint_map`): a shipped
map (:data:`JOINT_MAPS`) when one fits the clip, else the joint matcher
(:mod:`loosefit.body.joint_match`, by name and by structure), or a map file the
user writes (:func:`~loosefit.body.joint_maps.load_joint_map_file`).

Any rest pose works (a T-pose, an A-pose, arms down; bones along any axis): the
limbs are aligned by their rest directions, and only the rotation channels of the
joints and their OFFSETs (the rest pose) are read, except the root's path: the
mapped root's world position, with the position channels of it and of the joints
above it as :func:`~loosefit.body.bvh.read_bvh` reads them (added to the OFFSET).
Position channels on the other joints (studio files write six channels on every
joint, repeating the offset) are ignored. A studio file whose root joint channels
repeat the offset moves the root path by a constant, which recentring and
grounding remove.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from loosefit.body.avatar import Skeleton
from loosefit.body.bvh import _UNIT_SCALES, BvhClip, forward_kinematics, rest_positions
from loosefit.body.joint_maps import (  # noqa: F401 - JointMap, DAZ_MAP, CMU_MB_MAP re-exported
    CMU_MB_MAP,
    DAZ_MAP,
    JOINT_MAPS,
    JointMap,
    is_map_file,
    load_joint_map_file,
)
from loosefit.body.joint_match import JointMatch, match_skeleton
from loosefit.body.resample import filter_rotation_glitches, resample_motion
from loosefit.body.rotations import rotation_between
from loosefit.errors import LoosefitInputError
from loosefit.types import Motion

_AXES = {
    "+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0),
    "-y": (0, -1, 0), "+z": (0, 0, 1), "-z": (0, 0, -1),
}  # fmt: skip


@dataclass
class RetargetConfig:
    """How a motion capture file (BVH, glTF, SMPL .npz) is read and mapped onto the avatar."""

    # a name in JOINT_MAPS; "auto": a shipped map that fits the clip, else the joint matcher
    # (loosefit.body.joint_match); or a .yaml/.yml/.toml map file (load_joint_map_file)
    joint_map: str = "auto"
    source_up: str = "+y"  # the source's up axis (a map file's source_up overrides it)
    source_forward: str = "+z"  # the direction the source skeleton faces at zero rotation
    fps: float | None = 30.0  # resample to this rate (None keeps the source's)
    filter_glitches: bool = True  # remove single-frame rotation pops before retargeting
    recenter: bool = True  # start the root at x = y = 0
    ground: bool = True  # shift in z so the feet rest on the floor
    units: str = "auto"  # the file's length unit: "m", "cm", "mm", or "auto" (read_bvh's guess)
    scale: float | None = None  # metres per file unit; overrides units
    check_height: bool = True  # refuse a dancer outside DANCER_HEIGHT_M (units read wrong)
    animation: str | None = None  # glTF: the animation's name or index (None: the first)
    skin: str | None = None  # glTF: the skin's name or index (None: the one animated most)
    smpl_up: str = "auto"  # SMPL .npz: its world's up axis, +z for AMASS ("auto": detected)


# A dancer's standing height, estimated from the hip-to-ankle length of the legs (the
# hip, knee and ankle joints) over this fraction of an adult's stature (anthropometric
# tables give 0.47-0.49; the default avatar's is 0.485), must lie in this range (m): a
# file read in the wrong unit is off by a factor of 10 or more.
LEG_TO_HEIGHT = 0.48
DANCER_HEIGHT_M = (1.2, 2.2)


def axis_change(up: str, forward: str) -> np.ndarray:
    """(3, 3) rotation taking a source frame (up, forward) to the avatar's (+Z up, -Y forward)."""
    if up not in _AXES or forward not in _AXES:
        raise LoosefitInputError(
            "RetargetConfig", "source_up/source_forward", f"one of {list(_AXES)}", f"{up}/{forward}"
        )
    u, f = np.array(_AXES[up], float), np.array(_AXES[forward], float)
    if abs(u @ f) > 0:
        raise LoosefitInputError(
            "RetargetConfig", "source_up/source_forward", "perpendicular axes", f"{up}/{forward}"
        )
    src = np.stack([np.cross(u, f), u, f], 1)  # columns: left, up, forward
    dst = np.stack([np.array([1.0, 0, 0]), np.array([0, 0, 1.0]), np.array([0, -1.0, 0])], 1)
    return dst @ src.T


def _fits(jmap: JointMap, names: set[str]) -> bool:
    """Whether a map finds the clip's root and every limb it aligns (retarget_bvh's needs)."""
    needed = ["Hips", *(a for a in jmap.align if a in jmap.joints)]
    return all(jmap.joints.get(a) in names for a in needed)


def choose_joint_map(
    source_names: list[str] | tuple[str, ...],
    name: str = "auto",
    clip: BvhClip | None = None,
    config: RetargetConfig | None = None,
) -> JointMap:
    """The joint map by name or file, or for ``"auto"`` the one that fits the clip.

    ``"auto"``: the shipped map whose source joints the clip covers best; with ``clip``
    given, the best shipped map that fits it (its root and aligned limbs all present),
    else the joint matcher's map (see :func:`resolve_joint_map`).
    """
    if clip is not None:
        cfg = RetargetConfig(**{**(config or RetargetConfig()).__dict__, "joint_map": name})
        return resolve_joint_map(clip, cfg).joint_map
    if name != "auto":
        if is_map_file(name):
            return load_joint_map_file(name, source_names)
        if name not in JOINT_MAPS:
            raise LoosefitInputError(
                "RetargetConfig", "joint_map",
                f"one of {['auto', *JOINT_MAPS]} or a .yaml/.yml/.toml joint map file",
                repr(name),
            )  # fmt: skip
        return JOINT_MAPS[name]
    have = set(source_names)
    return max(
        JOINT_MAPS.values(),
        key=lambda m: sum(s in have for s in m.joints.values()) / len(m.joints),
    )


def resolve_joint_map(clip: BvhClip, config: RetargetConfig | None = None) -> JointMatch:
    """The joint map a clip is retargeted with, and how each avatar joint was matched.

    ``config.joint_map`` a shipped map's name: that map; a map file: the file
    (:func:`~loosefit.body.joint_maps.load_joint_map_file`, its joints checked against
    the clip's); ``"auto"``: the shipped maps first, the best covering one that fits the
    clip (so the CMU and DAZ files retarget as they always did), else the joint matcher
    (:func:`~loosefit.body.joint_match.match_skeleton`) on the clip's names and rest
    pose in the avatar's axes (``config.source_up``/``source_forward``).

    Raises:
        LoosefitInputError: an unknown map name, a bad map file, or a skeleton that no
            shipped map fits and the matcher cannot map (naming the file).
    """
    config = config or RetargetConfig()
    names = list(clip.joint_names)
    name = config.joint_map
    if name != "auto":
        jmap = choose_joint_map(names, name)
        if jmap.joints:
            how = "map file" if is_map_file(name) else f"map {jmap.name}"
            return JointMatch(jmap, dict.fromkeys(jmap.joints, how))
        # a map file with only the axes: matched automatically in them
        axes = {"source_up": jmap.source_up or config.source_up,
                "source_forward": jmap.source_forward or config.source_forward}  # fmt: skip
        match = resolve_joint_map(clip, replace(config, joint_map="auto", **axes))
        note = f"axes from {name}: up {axes['source_up']}, forward {axes['source_forward']}"
        return JointMatch(replace(match.joint_map, **axes), match.how, (*match.notes, note))
    have = set(names)
    by_cover = sorted(
        JOINT_MAPS.values(),
        key=lambda m: -sum(s in have for s in m.joints.values()) / len(m.joints),
    )
    for jmap in by_cover:  # fmt: skip
        if _fits(jmap, have):
            present = {a: s for a, s in jmap.joints.items() if s in have}
            return JointMatch(jmap, dict.fromkeys(present, f"map {jmap.name}"))
    C = axis_change(config.source_up, config.source_forward)
    return match_skeleton(names, clip.parents, rest_positions(clip) @ C.T, str(clip.path))


def _axes(jmap: JointMap, config: RetargetConfig) -> np.ndarray:
    """The axis change for a clip: a map file's axes, else the configuration's."""
    up = jmap.source_up or config.source_up
    return axis_change(up, jmap.source_forward or config.source_forward)


def _world_fk(skeleton: Skeleton, world: np.ndarray, root: np.ndarray) -> np.ndarray:
    """(T, J, 3) joint positions of the avatar from world rotation deltas (T, J, 3, 3)."""
    pos = np.zeros(world.shape[:2] + (3,))
    for j, p in enumerate(skeleton.parents):
        if p < 0:
            pos[:, j] = root
        else:
            pos[:, j] = pos[:, p] + world[:, p] @ (skeleton.heads[j] - skeleton.heads[p])
    return pos


def _leg_length(positions: np.ndarray, names, hip: str, knee: str, ankle: str) -> float | None:
    try:
        a, b, c = (positions[names.index(n)] for n in (hip, knee, ankle))
    except ValueError:
        return None
    return float(np.linalg.norm(b - a) + np.linalg.norm(c - b))


def source_height(clip: BvhClip, config: RetargetConfig | None = None) -> tuple[float, str]:
    """The dancer's standing height in metres, as the clip was read, and how it was measured.

    From the legs' hip-to-ankle length at rest over :data:`LEG_TO_HEIGHT` when the joint
    map finds the left leg; otherwise the rest skeleton's extent (joints and End Sites)
    along ``config.source_up``.
    """
    config = config or RetargetConfig()
    names = list(clip.joint_names)
    try:
        jmap = resolve_joint_map(clip, config).joint_map
    except LoosefitInputError:  # no legs found: measure the extent; retarget_bvh explains
        jmap = JointMap("none", {})
    C = _axes(jmap, config)
    rest = rest_positions(clip) @ C.T
    legs = [jmap.joints.get(n) for n in ("LeftUpLeg", "LeftLeg", "LeftFoot")]
    leg = _leg_length(rest, names, *legs) if all(n in names for n in legs) else None
    if leg:
        return leg / LEG_TO_HEIGHT, f"legs {leg:.3g} m hip to ankle"
    ends = [rest[j] + C @ np.asarray(o) for j, o in clip.end_offsets.items()]
    z = np.vstack([rest, *ends])[:, 2] if ends else rest[:, 2]
    return float(z.max() - z.min()), "the rest skeleton's extent"


def check_source_height(clip: BvhClip, config: RetargetConfig | None = None) -> float:
    """The dancer's height (:func:`source_height`), refused outside :data:`DANCER_HEIGHT_M`.

    Raises:
        LoosefitInputError: naming the file, the measured height and how the units were
            read, with the options that set them.
    """
    height, how = source_height(clip, config)
    low, high = DANCER_HEIGHT_M
    if not low <= height <= high:
        unit = {v: k for k, v in _UNIT_SCALES.items()}.get(clip.units_scale)
        read = f"read in {unit}" if unit else f"read at {clip.units_scale:g} m per unit"
        raise LoosefitInputError(
            str(clip.path), "units",
            f"a dancer {low:g}-{high:g} m tall",
            f"{height:.2f} m ({how}, {read})",
            hint="give the file's length unit: --units m|cm|mm or --scale METRES_PER_UNIT "
                 "(`loosefit motion`), or the motion spec units:cm:FILE.bvh or "
                 "scale:F:FILE.bvh (any command, a preset, the Python API)",
        )  # fmt: skip
    return height


def retarget_bvh(
    clip: BvhClip,
    skeleton: Skeleton,
    floor_height: float,
    config: RetargetConfig | None = None,
    name: str | None = None,
) -> Motion:
    """A BVH clip as a :class:`Motion` on the avatar's skeleton.

    Args:
        clip: the parsed BVH (see :func:`loosefit.body.bvh.read_bvh`).
        skeleton: the avatar's skeleton (``Avatar.skeleton``).
        floor_height: height of the avatar's root above its soles at rest
            (``Avatar.floor_height``).
        config: options; defaults to :class:`RetargetConfig`.
        name: the motion's name (default: the file's stem).

    Returns:
        The motion, resampled to ``config.fps``.
    """
    config = config or RetargetConfig()
    src_names = list(clip.joint_names)
    jmap = resolve_joint_map(clip, config).joint_map  # a skeleton it cannot map: say so first
    if config.check_height:
        check_source_height(clip, config)
    source = str(clip.path)
    root_name = skeleton.names[0]
    if jmap.joints.get(root_name) not in src_names:
        raise LoosefitInputError(
            source,
            "HIERARCHY",
            f"the root joint '{jmap.joints.get(root_name)}' of the '{jmap.name}' joint map",
            f"joints {src_names[:8]}...",
            hint="pass a joint map that matches this skeleton",
        )
    present = {a: src_names.index(s) for a, s in jmap.joints.items() if s in src_names}
    needed = [a for a in jmap.align if a in jmap.joints and a not in present]
    if needed:
        raise LoosefitInputError(
            source,
            "HIERARCHY",
            f"the joints {[jmap.joints[a] for a in needed]} of the '{jmap.name}' joint map",
            "them missing",
        )

    rotations = clip.rotations.astype(np.float64)
    if config.filter_glitches:
        rotations = filter_rotation_glitches(rotations, clip.fps)
    C = _axes(jmap, config)
    src_pos, src_world = forward_kinematics(
        BvhClip(**{**clip.__dict__, "rotations": rotations})
    )  # (T, Js, 3), (T, Js, 3, 3)
    src_world = C @ src_world @ C.T
    src_pos = src_pos @ C.T
    src_rest = rest_positions(clip) @ C.T  # (Js, 3)
    src_parents = np.asarray(clip.parents)

    def is_descendant(b: int, ancestor: int) -> bool:
        while b >= 0:
            b = src_parents[b]
            if b == ancestor:
                return True
        return False

    # 1. Rest-pose alignment A_a of every avatar bone.
    J = len(skeleton.names)
    align = np.tile(np.eye(3), (J, 1, 1))
    for a, an in enumerate(skeleton.names):
        p = skeleton.parents[a]
        align[a] = align[p] if p >= 0 else np.eye(3)
        if an not in jmap.align or an not in present:
            continue
        b = present[an]
        kids = [c for c in skeleton.children(a) if skeleton.names[c] in present]
        kids = [c for c in kids if is_descendant(present[skeleton.names[c]], b)]
        if kids:
            c = min(kids, key=lambda c: np.linalg.norm(skeleton.heads[c] - skeleton.tails[a]))
            d_av = skeleton.heads[c] - skeleton.heads[a]
            d_src = src_rest[present[skeleton.names[c]]] - src_rest[b]
        elif b in clip.end_offsets:
            d_av = skeleton.tails[a] - skeleton.heads[a]
            d_src = C @ clip.end_offsets[b]
        else:
            continue
        if np.linalg.norm(d_src) > 1e-9 and np.linalg.norm(d_av) > 1e-9:
            align[a] = rotation_between(d_av[None], d_src[None])[0].astype(np.float64)

    # 2. World rotation deltas of the avatar's bones.
    T = clip.rotations.shape[0]
    world = np.zeros((T, J, 3, 3))
    for a, an in enumerate(skeleton.names):
        p = skeleton.parents[a]
        if an in present:
            world[:, a] = src_world[:, present[an]] @ align[a]
        else:
            world[:, a] = world[:, p] if p >= 0 else np.eye(3)

    # 3. Local rotations.
    local = np.empty_like(world)
    local[:, 0] = world[:, 0]
    par = skeleton.parents[1:]
    local[:, 1:] = np.swapaxes(world[:, par], -1, -2) @ world[:, 1:]

    # 4. Root translation, scaled by leg length.
    root = src_pos[:, present[root_name]].copy()
    av_leg = _leg_length(skeleton.heads, skeleton.names, "LeftUpLeg", "LeftLeg", "LeftFoot")
    src_leg = None
    legs = [jmap.joints.get(n) for n in ("LeftUpLeg", "LeftLeg", "LeftFoot")]
    if all(n in src_names for n in legs):
        src_leg = _leg_length(src_rest, src_names, *legs)
    scale = av_leg / src_leg if av_leg and src_leg else 1.0
    root = root * scale
    if config.recenter:
        root[:, :2] -= root[0, :2]
    if config.ground:
        pos = _world_fk(skeleton, world, root)
        feet = [skeleton.names.index(n) for n in skeleton.names if "Foot" in n or "Toe" in n]
        # Height of each foot joint above the floor at the avatar's rest pose.
        rest_h = skeleton.heads[feet, 2] + floor_height
        lowest = (pos[:, feet, 2] - rest_h).min(1)  # (T,) sole height per frame
        root[:, 2] -= np.percentile(lowest, 5)

    motion = Motion(
        joint_names=skeleton.names,
        rotations=local.astype(np.float32),
        root_translation=root.astype(np.float32),
        fps=clip.fps,
        name=name or (clip.path.stem if clip.path is not None else "bvh"),
        meta={
            "source": source,
            "joint_map": jmap.name,
            "scale": scale,
            "units_scale": clip.units_scale,
        },
    )
    if config.fps is not None and abs(config.fps - clip.fps) > 1e-6:
        motion = resample_motion(motion, config.fps)
    return motion
