"""Retargeting motion capture to the avatar's skeleton.

Which source joint drives each avatar joint (:func:`resolve_joint_map`): a shipped
map (:data:`JOINT_MAPS`) when one fits the clip, else the joint matcher
(:mod:`loosefit.motion.joint_match`, by name and by structure, on the zero pose or, when
that shows no legs, on the capture's frames), or a map file the user writes
(:func:`~loosefit.motion.joint_maps.load_joint_map_file`).

How the avatar moves (:func:`retarget_bvh`): from what the capture shows, its joints'
world positions and orientations frame by frame (forward kinematics), bone by bone
(:mod:`loosefit.motion.bone_directions`): each mapped limb points where the source's
bone points at every frame, and turns with the source joint about it; the pelvis,
spine, neck and head turn with their source joints, calibrated on landmarks (the
left-right axes of hips and shoulders, the trunk's line). A zero pose that stands as
the avatar's rest does (a T-pose, an A-pose) is used as the calibration instead, as it
always was; any other (bones along X or Y, joint orients baked into the rotations) is
not needed. Unmapped avatar joints follow their parent rigidly. Local rotations are
then ``R_a = G_parent^T G_a``.

The source's axes (:func:`source_axes`): its up axis is found from the frames (the
feet-to-head direction of the joints so named) unless given; a shipped or written map
may give both. The dancer's height (:func:`source_height`) is measured on the frames,
standing (:mod:`loosefit.motion.capture_measure`).

The root translation is the source root's position scaled by the ratio of the
two skeletons' leg lengths, recentred to start at the origin in XY, and shifted
in Z so the feet rest on the floor. Only the root's position channels (and those of
the joints above it) move the body; studio files' six channels on every joint
(repeating the offset) are read as the file says, which changes nothing.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from loosefit.body.avatar import Skeleton
from loosefit.errors import LoosefitInputError
from loosefit.motion.bone_directions import REFERENCES, SourcePose, solve_bone_rotations
from loosefit.motion.bvh import _UNIT_SCALES
from loosefit.motion.capture_measure import (
    FORWARD_FOR_UP,
    HeightMeasure,
    face_forward,
    guess_up,
    matching_frames,
    measure_height,
)
from loosefit.motion.joint_map_files import check_joint_map
from loosefit.motion.joint_maps import (  # noqa: F401 - JointMap, DAZ_MAP, CMU_MB_MAP re-exported
    CMU_MB_MAP,
    DAZ_MAP,
    JOINT_MAPS,
    JointMap,
    is_map_file,
    load_joint_map_file,
)
from loosefit.motion.joint_match import JointMatch, match_skeleton
from loosefit.motion.match_errors import MATCH_EXPECTED, SkeletonMatchError, map_file_hint
from loosefit.motion.pose_check import check_pose
from loosefit.motion.resample import filter_rotation_glitches, resample_motion
from loosefit.motion.skeleton_clip import BvhClip, forward_kinematics, rest_positions
from loosefit.types import Motion

_AXES = {
    "+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0),
    "-y": (0, -1, 0), "+z": (0, 0, 1), "-z": (0, 0, -1),
}  # fmt: skip


@dataclass
class RetargetConfig:
    """How a motion capture file (BVH, glTF, SMPL .npz) is read and mapped onto the avatar.

    ``joint_map`` "auto" takes a shipped map that fits the clip, else the joint matcher
    (:mod:`loosefit.motion.joint_match`). ``source_up`` "auto" is a BVH file's up axis from
    its frames (feet to head), else +y (glTF, SMPL); a map file's ``source_up`` overrides
    it. ``source_forward`` "auto" is +z for a Y-up source, -y for a Z-up one
    (``FORWARD_FOR_UP``). ``reference`` (:mod:`loosefit.motion.bone_directions`):
    "zero-pose" when the source's zero pose stands like the avatar's rest, "clip" from
    landmarks and bends over the clip (any zero pose), "auto" the first when it stands so.
    """

    joint_map: str = "auto"  # a name in JOINT_MAPS, "auto", or a .yaml/.yml/.toml map file
    source_up: str = "auto"  # the source's up axis, +x..-z, or "auto"
    source_forward: str = "auto"  # the way the source faces, +x..-z, or "auto"
    reference: str = "auto"  # how each bone's turn is calibrated: "zero-pose", "clip", "auto"
    fps: float | None = 30.0  # resample to this rate (None keeps the source's)
    filter_glitches: bool = True  # remove single-frame rotation pops before retargeting
    recenter: bool = True  # start the root at x = y = 0
    ground: bool = True  # shift in z so the feet rest on the floor
    units: str = "auto"  # the file's length unit: "m", "cm", "mm", or "auto" (read_bvh's guess)
    scale: float | None = None  # metres per file unit; overrides units
    check_height: bool = True  # refuse a dancer outside DANCER_HEIGHT_M (units read wrong)
    check_pose: bool = True  # refuse a motion no dancer could dance (loosefit.motion.pose_check)
    animation: str | None = None  # glTF: the animation's name or index (None: the first)
    skin: str | None = None  # glTF: the skin's name or index (None: the one animated most)
    smpl_up: str = "auto"  # SMPL .npz: its world's up axis, +z for AMASS ("auto": detected)


# A dancer's standing height (loosefit.motion.capture_measure.measure_height) must lie in
# this range (m): a file read in the wrong unit is off by a factor of 10 or more.
DANCER_HEIGHT_M = (1.2, 2.2)
# Units a file may be in that --units does not name: metres per unit.
OTHER_UNITS = {"inches": 0.0254, "feet": 0.3048}


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
                "RetargetConfig",
                "joint_map",
                f"one of {['auto', *JOINT_MAPS]} or a .yaml/.yml/.toml joint map file",
                repr(name),
            )
        return JOINT_MAPS[name]
    have = set(source_names)
    return max(
        JOINT_MAPS.values(),
        key=lambda m: sum(s in have for s in m.joints.values()) / len(m.joints),
    )


def source_axes(
    clip: BvhClip, config: RetargetConfig | None = None, jmap: JointMap | None = None
) -> tuple[str, str, str]:
    """The source's up and forward axes, and how up was decided.

    A map (file) that gives them, else ``config``; ``"auto"`` up: for a BVH file, the
    signed axis from its feet to its head over the frames
    (:func:`~loosefit.motion.capture_measure.guess_up`), else ``+y`` (glTF and SMPL clips
    are Y up); ``"auto"`` forward: :data:`FORWARD_FOR_UP` of the up axis.

    Returns:
        (up, forward, how): e.g. ("+z", "-y", "found from the frames (feet to head)"),
        ("+y", "+z", "glTF's").
    """
    config = config or RetargetConfig()
    up = (jmap.source_up if jmap is not None else None) or config.source_up
    how = "given"
    if up == "auto":
        form = clip.meta.get("format")
        if form is not None:  # glTF is Y up; SMPL clips are turned Y up as they are read
            up, how = "+y", f"{form}'s"
        else:  # a BVH file: its axes are its writer's choice
            found = guess_up(clip.joint_names, _kinematics(clip)[0])
            up, how = (
                (found, "found from the frames (feet to head)")
                if found
                else ("+y", "default: no head and feet named")
            )
    forward = (jmap.source_forward if jmap is not None else None) or config.source_forward
    if forward == "auto":
        forward = FORWARD_FOR_UP.get(up, "+z")
    return up, forward, how


def _match_on_frames(clip: BvhClip, C: np.ndarray) -> JointMatch:
    """The joint matcher on the zero pose, else on the capture's frames (a rig whose zero
    pose does not stand, e.g. every bone along X): the first frame that shows a pelvis
    with legs below it and a spine with arms; sides decided by position are taken with
    the frame turned to face -Y by its feet.

    Raises:
        SkeletonMatchError: when neither the zero pose nor any frame tried shows a
            humanoid: what was found on the frame that came closest and on the zero pose,
            and the map file lines the names suggest.
    """
    names, parents, source = list(clip.joint_names), clip.parents, str(clip.path)
    try:
        return match_skeleton(names, parents, rest_positions(clip) @ C.T, source)
    except SkeletonMatchError as exc:
        first = exc
    frames = matching_frames(clip.num_frames)
    positions = _kinematics(clip)[0].astype(np.float64) @ C.T  # (T, Js, 3)
    closest: tuple[int, SkeletonMatchError] | None = None
    for t in frames:
        try:
            match = match_skeleton(names, parents, positions[t], source)
        except SkeletonMatchError as exc:
            if closest is None or len(exc.missing) < len(closest[1].missing):
                closest = (t, exc)
            continue
        note = f"matched on frame {t}: the zero pose shows no legs below the pelvis"
        joints = match.joint_map.joints
        if any("sides by structure" in n for n in match.notes):
            fwd = [
                positions[t, names.index(joints[f"{S}ToeBase"])]
                - positions[t, names.index(joints[f"{S}Foot"])]
                for S in ("Left", "Right")
                if f"{S}ToeBase" in joints
            ]
            fwd = np.mean(fwd, axis=0) * [1, 1, 0] if fwd else np.zeros(3)
            if np.linalg.norm(fwd) > 1e-6:  # the feet point forward
                turned = face_forward(positions[t], fwd)
                match = match_skeleton(names, parents, turned, source)
                note += ", turned to face -Y by its feet"
        return JointMatch(match.joint_map, match.how, (*match.notes, note))
    t, best = closest if closest is not None else (None, first)
    on_frames = (
        f"on frame {t} of the frames tried ({frames}), the closest: {'; '.join(best.notes)}"
        if t is not None
        else "no frames to try"
    )
    guesses = {**first.guesses, **best.guesses}
    raise SkeletonMatchError(
        source,
        "HIERARCHY",
        MATCH_EXPECTED,
        f"nothing for {list(best.missing)} in the frames or the zero pose "
        f"({'; '.join(best.details)}; {on_frames}; on "
        f"the zero pose: {'; '.join(first.notes)}; the file's {len(names)} joints: "
        f"{', '.join(names[:40])}{'...' if len(names) > 40 else ''})",
        hint=map_file_hint(source, guesses),
        missing=best.missing,
        notes=best.notes,
        guesses=guesses,
        details=best.details,
    )


def resolve_joint_map(clip: BvhClip, config: RetargetConfig | None = None) -> JointMatch:
    """The joint map a clip is retargeted with, and how each avatar joint was matched.

    ``config.joint_map`` a shipped map's name: that map; a map file: the file
    (:func:`~loosefit.motion.joint_maps.load_joint_map_file`, its joints checked against
    the clip's); ``"auto"``: the shipped maps first, the best covering one that fits the
    clip (so the CMU and DAZ files retarget as they always did), else the joint matcher
    (:func:`~loosefit.motion.joint_match.match_skeleton`) in the avatar's axes
    (:func:`source_axes`), on the zero pose, or when that shows no legs, on the frames.

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
            if is_map_file(name):  # a user's map: it must fit the skeleton
                positions = _kinematics(clip)[0]
                check_joint_map(jmap.joints, names, clip.parents, positions, str(clip.path), name)
            return JointMatch(jmap, dict.fromkeys(jmap.joints, how))
        # a map file with only the axes: matched automatically in them
        axes = {
            "source_up": jmap.source_up or config.source_up,
            "source_forward": jmap.source_forward or config.source_forward,
        }
        match = resolve_joint_map(clip, replace(config, joint_map="auto", **axes))
        note = f"axes from {name}: up {axes['source_up']}, forward {axes['source_forward']}"
        return JointMatch(replace(match.joint_map, **axes), match.how, (*match.notes, note))
    have = set(names)
    by_cover = sorted(
        JOINT_MAPS.values(),
        key=lambda m: -sum(s in have for s in m.joints.values()) / len(m.joints),
    )
    for jmap in by_cover:
        if _fits(jmap, have):
            present = {a: s for a, s in jmap.joints.items() if s in have}
            return JointMatch(jmap, dict.fromkeys(present, f"map {jmap.name}"))
    up, forward, _ = source_axes(clip, config)
    return _match_on_frames(clip, axis_change(up, forward))


def _axes(jmap: JointMap, config: RetargetConfig, clip: BvhClip) -> np.ndarray:
    """The axis change for a clip (:func:`source_axes`)."""
    return axis_change(*source_axes(clip, config, jmap)[:2])


def _kinematics(clip: BvhClip, root: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """World positions (T, Js, 3) and rotations (T, Js, 3, 3) of a clip, in its own axes,
    with only the position channels of ``root`` (default: the file's root) and the joints
    above it: the others' (studio files write them on every joint, repeating the offset)
    are left out, the bones keep their OFFSETs."""
    translations = np.broadcast_to(clip.offsets, clip.local_translations.shape).copy()
    j = 0 if root is None else root
    while j >= 0:
        translations[:, j] = clip.local_translations[:, j]
        j = int(clip.parents[j])
    return forward_kinematics(replace(clip, local_translations=translations))


def source_pose(clip: BvhClip, C: np.ndarray, root: int | None = None) -> SourcePose:
    """A clip's forward kinematics in the avatar's axes (``C`` from :func:`axis_change`),
    moved by the position channels of ``root`` and the joints above it (:func:`_kinematics`)."""
    pos, world = _kinematics(clip, root)  # (T, Js, 3), (T, Js, 3, 3)
    pos, world = pos.astype(np.float64), world.astype(np.float64)
    rest = rest_positions(clip).astype(np.float64)
    kids: dict[int, list[int]] = {}
    for j, p in enumerate(clip.parents):
        kids.setdefault(int(p), []).append(j)
    leaf = {}
    for j in range(clip.num_joints):
        if j in clip.end_offsets:
            off = np.asarray(clip.end_offsets[j], np.float64)
            leaf[j] = ((world[:, j] @ off) @ C.T, C @ off)
        elif len(kids.get(j, [])) == 1:
            k = kids[j][0]
            leaf[j] = ((pos[:, k] - pos[:, j]) @ C.T, C @ (rest[k] - rest[j]))
    return SourcePose(
        positions=pos @ C.T,
        rotations=C @ world @ C.T,
        parents=np.asarray(clip.parents),
        rest=rest @ C.T,
        leaf=leaf,
    )


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


def measure_source_height(clip: BvhClip, config: RetargetConfig | None = None) -> HeightMeasure:
    """The dancer's standing height in metres, as the clip was read, measured on its frames
    (:func:`~loosefit.motion.capture_measure.measure_height`): the head above the ankles at
    the most extended frame, or without a joint map, the skeleton's extent."""
    config = config or RetargetConfig()
    names = list(clip.joint_names)
    try:
        jmap = resolve_joint_map(clip, config).joint_map
    except LoosefitInputError:  # no legs found: measure the extent; retarget_bvh explains
        jmap = JointMap("none", {})
    C = _axes(jmap, config, clip)
    present = {a: names.index(s) for a, s in jmap.joints.items() if s in names}
    pose = source_pose(clip, C, present.get("Hips"))
    ends = [pose.positions[:, j] + d for j, (d, _) in pose.leaf.items() if j in clip.end_offsets]
    extra = np.stack(ends, axis=1) if ends else None  # (T, E, 3)
    return measure_height(pose.positions, present, extra)


def source_height(clip: BvhClip, config: RetargetConfig | None = None) -> tuple[float, str]:
    """The dancer's height in metres and how it was measured (:func:`measure_source_height`)."""
    measure = measure_source_height(clip, config)
    return measure.height, measure.how


def _height_hint(clip: BvhClip, height: float) -> str:
    """What would make a dancer of a height outside the range: a unit, a scale, or neither."""
    low, high = DANCER_HEIGHT_M
    spec = f"units:UNIT:{clip.path.name}" if clip.path is not None else "units:UNIT:FILE"
    for unit, factor in _UNIT_SCALES.items():
        h = height / clip.units_scale * factor
        if factor != clip.units_scale and low <= h <= high:
            return (
                f"read in {unit} it is {h:.2f} m: --units {unit} (`loosefit motion`, "
                f"`animate`, ...), or the motion spec {spec.replace('UNIT', unit)} (any "
                "command, a preset, the Python API)"
            )
    for unit, factor in OTHER_UNITS.items():
        h = height / clip.units_scale * factor
        if low <= h <= high:
            return (
                f"in {unit} it is {h:.2f} m: --scale {factor:g} (`loosefit motion`, "
                f"`animate`, ...), or the motion spec scale:{factor:g}:{clip.path.name}"
            )
    return (
        "no unit makes a dancer of it, so the measure itself may be wrong: see how the "
        f"joints map and what the frames show with `loosefit inspect-motion "
        f"{clip.path.name} --sheet sheet.png`, and give --joint-map"
    )


def check_source_height(clip: BvhClip, config: RetargetConfig | None = None) -> float:
    """The dancer's height (:func:`measure_source_height`), refused outside
    :data:`DANCER_HEIGHT_M`.

    Raises:
        LoosefitInputError: naming the file, the measured height, the frame and how the
            units were read, with the unit or scale that would fix it (when one would).
    """
    measure = measure_source_height(clip, config)
    height = measure.height
    low, high = DANCER_HEIGHT_M
    if not low <= height <= high:
        unit = {v: k for k, v in _UNIT_SCALES.items()}.get(clip.units_scale)
        read = f"read in {unit}" if unit else f"read at {clip.units_scale:g} m per unit"
        raise LoosefitInputError(
            str(clip.path),
            "units",
            f"a dancer {low:g}-{high:g} m tall",
            f"{height:.2f} m ({measure.how}; {read})",
            hint=_height_hint(clip, height),
        )
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
        clip: the parsed BVH (see :func:`loosefit.motion.bvh.read_bvh`).
        skeleton: the avatar's skeleton (``Avatar.skeleton``).
        floor_height: height of the avatar's root above its soles at rest
            (``Avatar.floor_height``).
        config: options; defaults to :class:`RetargetConfig`.
        name: the motion's name (default: the file's stem).

    Returns:
        The motion, resampled to ``config.fps``.

    Raises:
        LoosefitInputError: a skeleton it cannot map, a dancer of no human height
            (``config.check_height``), a motion no dancer could dance
            (``config.check_pose``, :func:`~loosefit.motion.pose_check.check_pose`).
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

    if config.reference not in REFERENCES:
        raise LoosefitInputError(
            "RetargetConfig", "reference", f"one of {list(REFERENCES)}", repr(config.reference)
        )
    rotations = clip.rotations.astype(np.float64)
    if config.filter_glitches:
        rotations = filter_rotation_glitches(rotations, clip.fps)
    up, forward, _ = source_axes(clip, config, jmap)
    C = axis_change(up, forward)
    src = source_pose(replace(clip, rotations=rotations), C, present[root_name])
    src_pos = src.positions  # (T, Js, 3)
    src_rest = src.rest  # (Js, 3)

    # 1-2. World rotations of the avatar's bones, from the source's, bone by bone.
    bones = solve_bone_rotations(skeleton, src, present, jmap.align, config.reference)
    world = bones.world  # (T, J, 3, 3)

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
            "reference": bones.reference,
            "axes": f"up {up}, forward {forward}",
        },
    )
    if config.check_pose:  # at the capture's own rate: a joint's flip shows there
        check_pose(motion, skeleton, floor_height, source)
    if config.fps is not None and abs(config.fps - clip.fps) > 1e-6:
        motion = resample_motion(motion, config.fps)
    return motion
