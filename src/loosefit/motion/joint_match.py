"""Matching any humanoid skeleton's joints to the avatar's, by name and by structure.

A BVH file from another tool names its joints its own way (``mixamorig:LeftUpLeg``,
``thigh_l``, ``left_hip``, ``UpperLeg_L``, ``lThigh``...). :func:`match_skeleton`
finds the avatar joints that retargeting needs in three steps:

1. **Names.** Each name is cut into a side and a body part
   (:func:`~loosefit.motion.joint_names.classify_joint_name`): a namespace (``xxx:``) and
   prefixes such as ``mixamorig``, ``joint_`` or ``Bip01`` are dropped; the side is
   ``Left``/``Right``, ``L``/``R``/``l``/``r`` before a capital or a separator, or
   ``_L``/``.L``/``_l``/``Left`` at the end, in any case; the part comes from synonyms
   (``UpLeg``/
   ``Thigh``/``UpperLeg``, ``Leg``/``Shin``/``Calf``/``LowerLeg``/``Knee``,
   ``Foot``/``Ankle``, ``Toe``/``ToeBase``/``Ball``, ``Collar``/``Clavicle``,
   ``Arm``/``UpperArm``/``Shldr``, ``ForeArm``/``LowerArm``/``Elbow``,
   ``Hand``/``Wrist``, ``Spine``/``Chest``/``Abdomen``, ``Neck``, ``Head``,
   ``Hips``/``Pelvis``/``Root``). ``Shoulder`` is a collar before an upper arm and an
   upper arm after a collar; a sided ``Hip`` is a thigh unless a thigh follows it;
   ``Foot`` after an ``Ankle`` is the toe (SMPL).
2. **Structure.** The pelvis is the named root that branches, else the first joint
   that branches. Its branches that reach far below it are the legs; the one that
   reaches highest is the torso. The spine path runs from the pelvis to the head;
   the two longest branches off it are the arms, and the joint they branch from is
   the chest (the avatar's ``Spine1``). Along a leg the two longest consecutive
   bones are thigh and shin (then foot and toe; a joint before the thigh is the hip
   joint); along an arm, upper arm and forearm (then the hand; a joint before is the
   collar). Names place a joint on its chain where they can; structure fills the rest.
3. **Sides.** By the names in a limb; failing that, by the side of its rest pose:
   the avatar's left is +X once the source's up and forward axes are applied.

The result (:class:`JointMatch`) says for each avatar joint which source joint
drives it and how that was decided, for ``loosefit inspect-motion`` to print.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from loosefit.motion.joint_maps import LIMBS, JointMap
from loosefit.motion.joint_names import END_MARKER, REQUIRED, NameParts, classify_joint_name
from loosefit.motion.match_errors import raise_no_match


@dataclass(frozen=True)
class JointMatch:
    """Which source joint drives each avatar joint, and how that was decided.

    Attributes:
        joint_map: the map (``name="auto-matched"`` from :func:`match_skeleton`), as
            :func:`~loosefit.motion.retarget.retarget_bvh` uses it.
        how: avatar joint -> "name", "structure", "map file" or "map NAME".
        notes: the decisions behind the chains (pelvis, torso, sides), to print.
    """

    joint_map: JointMap
    how: dict[str, str]
    notes: tuple[str, ...] = field(default_factory=tuple)


def _path(parents: np.ndarray, top: int, bottom: int) -> list[int]:
    """Joints from ``top`` (excluded) down to ``bottom`` (included); [] if not below it."""
    out = []
    j = bottom
    while j >= 0 and j != top:
        out.append(j)
        j = int(parents[j])
    return out[::-1] if j == top else []


def _first(chain_parts: list[str | None], wanted: tuple[str, ...], start: int = 0) -> int | None:
    for i in range(max(start, 0), len(chain_parts)):
        if chain_parts[i] in wanted:
            return i
    return None


def _longest_pair(points: np.ndarray) -> int | None:
    """Index i where bones i -> i+1 -> i+2 of a chain (K, 3) are longest together."""
    if len(points) < 3:
        return None
    bones = np.linalg.norm(np.diff(points, axis=0), axis=1)  # (K - 1,)
    return int(np.argmax(bones[:-1] + bones[1:]))


def _leg_roles(parts: list[str | None], points: np.ndarray) -> dict[str, tuple[int, str]]:
    """Chain index and how, for hipjoint/thigh/shin/foot/toe along a leg chain."""
    thigh = _first(parts, ("thigh",))
    if thigh is None:
        thigh = _first(parts, ("hip",))  # SMPL's left_hip is the thigh
    hipjoint = _first(parts[: thigh if thigh is not None else len(parts)], ("hipjoint", "hip"))
    shin = _first(parts, ("shin",), thigh + 1 if thigh is not None else 0)
    foot = _first(parts, ("foot",), shin + 1 if shin is not None else 0)
    toe = _first(parts, ("toe", "foot"), foot + 1) if foot is not None else None
    named = {"hipjoint": hipjoint, "thigh": thigh, "shin": shin, "foot": foot, "toe": toe}
    if thigh is None:
        thigh = shin - 1 if shin is not None else foot - 2 if foot is not None else None
        if thigh is None:
            thigh = _longest_pair(points)
    return _complete(named, ("hipjoint", "thigh", "shin", "foot", "toe"), thigh, len(parts))


def _arm_roles(parts: list[str | None], points: np.ndarray) -> dict[str, tuple[int, str]]:
    """Chain index and how, for collar/arm/forearm/hand along an arm chain."""
    collar = _first(parts, ("collar",))
    arm = _first(parts, ("upperarm",))
    shoulder = _first(parts, ("shoulder",))
    if shoulder is not None:
        if collar is not None and collar < shoulder:
            arm = shoulder if arm is None or arm < shoulder else arm
        elif arm is not None and arm > shoulder:
            collar = shoulder
        elif _first(parts, ("forearm",)) == shoulder + 1:
            arm = shoulder
    if collar is not None and arm is not None and collar > arm:
        collar = None
    forearm = _first(parts, ("forearm",), arm + 1 if arm is not None else 0)
    hand = _first(parts, ("hand",), forearm + 1 if forearm is not None else 0)
    named = {"collar": collar, "arm": arm, "forearm": forearm, "hand": hand}
    if arm is None:
        arm = forearm - 1 if forearm is not None else hand - 2 if hand is not None else None
        if arm is None:
            arm = _longest_pair(points)
    return _complete(named, ("collar", "arm", "forearm", "hand"), arm, len(parts))


def _complete(
    named: dict[str, int | None], order: tuple[str, ...], anchor: int | None, n: int
) -> dict[str, tuple[int, str]]:
    """Fill the roles names left open around the chain's anchor (thigh or upper arm).

    ``order`` is (joint before the anchor, anchor, the joints after it...). A role
    takes the next chain index after the previous role; a named index out of that
    order is dropped.
    """
    out: dict[str, tuple[int, str]] = {}
    if anchor is None or not 0 <= anchor < n:
        return out
    before, main, *after = order
    out[main] = (anchor, "name" if named[main] == anchor else "structure")
    b = named[before]
    if b is not None and b < anchor:
        out[before] = (b, "name")
    elif anchor >= 1:
        out[before] = (anchor - 1, "structure")
    prev = anchor
    for role in after:
        i = named[role]
        if i is not None and i == prev + 1:
            out[role] = (i, "name")
        elif i is not None and i > prev + 1:
            out[role] = (i, "name")  # joints between (twist bones) are skipped
        elif prev + 1 < n:
            out[role] = (prev + 1, "structure")
        else:
            break
        prev = out[role][0]
    return out


def _side(members: list[int], parts: list[NameParts], rest: np.ndarray) -> tuple[str | None, float]:
    """The side the names of a limb's joints give (or None), and its mean rest X."""
    sides = [parts[j].side for j in members if parts[j].side]
    side = None
    if sides:
        left = sides.count("L")
        side = "L" if left > len(sides) - left else "R" if left < len(sides) - left else None
    return side, float(rest[members, 0].mean())


def _two_sides(
    limbs: list[int], subtree: list[list[int]], parts: list[NameParts], rest: np.ndarray
) -> tuple[dict[str, int], str]:
    """{'L': branch, 'R': branch} for up to two limb branches, and how sides were told."""
    sides = [_side(subtree[c], parts, rest) for c in limbs]
    if len(limbs) == 2 and {sides[0][0], sides[1][0]} == {"L", "R"}:
        return {sides[0][0]: limbs[0], sides[1][0]: limbs[1]}, "name"
    if len(limbs) == 2:  # the avatar's left is +X
        left = 0 if sides[0][1] > sides[1][1] else 1
        return {"L": limbs[left], "R": limbs[1 - left]}, "structure"
    if len(limbs) == 1:
        s = sides[0][0] or ("L" if sides[0][1] > 0 else "R")
        return {s: limbs[0]}, "name" if sides[0][0] else "structure"
    return {}, "structure"


# The avatar joints of a match, in the order a JointMap lists them.
_AVATAR_ORDER = (
    "Hips",
    "LHipJoint",
    "LeftUpLeg",
    "LeftLeg",
    "LeftFoot",
    "LeftToeBase",
    "LowerBack",
    "Spine",
    "Spine1",
    "LeftShoulder",
    "LeftArm",
    "LeftForeArm",
    "LeftHand",
    "Neck",
    "Neck1",
    "Head",
    "RightShoulder",
    "RightArm",
    "RightForeArm",
    "RightHand",
    "RHipJoint",
    "RightUpLeg",
    "RightLeg",
    "RightFoot",
    "RightToeBase",
)


@dataclass(frozen=True)
class _SourceTree:
    """A source skeleton as the matcher walks it (J joints, parents before children).

    Attributes:
        names: the J joint names; ``parts``: what each name says; ``kinds``: its part.
        parents: (J,) int64 parent indices, -1 for a root.
        rest: (J, 3) float64 rest positions, the avatar's axes.
        kids: each joint's children.
        depth: (J,) int64 joints above each.
        subtree: each joint's subtree, itself first.
        legged: whether a joint's subtree holds a joint named as part of a leg.
        extent: the body's size (its height, or its arm span), measured over the
            pelvis's subtree once the pelvis is found (a root joint of no geometry metres
            away, where a capture's start position was baked in, is not the body): legs
            reach down a quarter of it below the pelvis, arms out 0.15 of it from the spine.
    """

    names: list[str]
    parts: list[NameParts]
    kinds: list[str | None]
    parents: np.ndarray
    rest: np.ndarray
    kids: list[list[int]]
    depth: np.ndarray
    subtree: list[list[int]]
    legged: list[bool]
    extent: float


def _source_tree(names: list[str], parents: np.ndarray, rest: np.ndarray) -> _SourceTree:
    """The walkable tree of (J,) names, (J,) int64 parents and (J, 3) rest positions."""
    J = len(names)
    parts = [classify_joint_name(n) for n in names]
    kinds = [p.part for p in parts]
    kids: list[list[int]] = [[] for _ in range(J)]
    depth = np.zeros(J, dtype=np.int64)
    for j, p in enumerate(parents):
        if p >= 0:
            kids[p].append(j)
            depth[j] = depth[p] + 1
    subtree: list[list[int]] = [[j] for j in range(J)]
    for j in range(J - 1, 0, -1):  # parents precede children
        if parents[j] >= 0:
            subtree[parents[j]] += subtree[j]
    extent = float(np.ptp(rest, axis=0).max()) if J else 0.0
    legged = [
        any(kinds[i] in ("thigh", "shin", "foot", "hip") for i in subtree[j]) for j in range(J)
    ]
    return _SourceTree(names, parts, kinds, parents, rest, kids, depth, subtree, legged, extent)


def _find_pelvis(tree: _SourceTree) -> tuple[int | None, str]:
    """The pelvis and how it was found, or None.

    A named root that branches (into the most named legs, then the deepest: a
    scene's "root" above the "pelvis"), else the first joint that branches.
    """
    kids, depth = tree.kids, tree.depth
    named_roots = [j for j in range(len(kids)) if tree.kinds[j] == "root" and len(kids[j]) >= 2]
    if named_roots:
        pelvis = max(named_roots, key=lambda j: (sum(tree.legged[c] for c in kids[j]), depth[j]))
        return pelvis, "name"
    if not kids:
        return None, "structure"
    j = int(np.flatnonzero(tree.parents < 0)[0])
    while len(kids[j]) == 1:
        j = kids[j][0]
    return (j if len(kids[j]) >= 2 else None), "structure"


def _torso(tree: _SourceTree, pelvis: int) -> tuple[int, int | None]:
    """The pelvis's branch that is the torso (holding the head, else reaching highest),
    and the named head joint nearest the pelvis (None when no joint is named so)."""
    heads = [j for j in tree.subtree[pelvis] if tree.kinds[j] == "head" and j != pelvis]
    top = min(heads, key=lambda j: tree.depth[j]) if heads else None
    branches = tree.kids[pelvis]
    if top is not None:
        return next(c for c in branches if top in tree.subtree[c]), top
    return max(branches, key=lambda c: tree.rest[tree.subtree[c], 2].max()), top


def _legs(tree: _SourceTree, pelvis: int, torso: int) -> list[int]:
    """Up to two of the pelvis's branches that reach far below it, lowest first; a branch
    whose joints are named as an arm and none as a leg is no leg (arms hanging from a
    chest taken for the pelvis, in a capture with no legs)."""
    rest, subtree = tree.rest, tree.subtree
    arm_kinds = ("collar", "shoulder", "upperarm", "forearm", "hand")
    low = {
        c: rest[subtree[c], 2].min()
        for c in tree.kids[pelvis]
        if c != torso
        and (tree.legged[c] or not any(tree.kinds[j] in arm_kinds for j in subtree[c]))
    }
    legs = [c for c in low if low[c] < rest[pelvis, 2] - 0.25 * tree.extent]
    named_legs = [c for c in legs if tree.legged[c]]
    return sorted(named_legs if len(named_legs) >= 2 else legs, key=lambda c: low[c])[:2]


def _leg_joints(tree: _SourceTree, pelvis: int, s: str, c: int) -> dict[str, tuple[int, str]]:
    """Avatar joint -> (source joint, how) along the leg branch ``c`` on side ``s``."""
    S = "Left" if s == "L" else "Right"
    lowest = max(tree.subtree[c], key=lambda j: (-tree.rest[j, 2], tree.depth[j]))
    chain = _path(tree.parents, pelvis, lowest)
    while len(tree.kids[chain[-1]]) == 1:
        chain.append(tree.kids[chain[-1]][0])
    roles = _leg_roles([tree.kinds[j] for j in chain], tree.rest[chain])
    avatar = {
        "hipjoint": f"{s}HipJoint",
        "thigh": f"{S}UpLeg",
        "shin": f"{S}Leg",
        "foot": f"{S}Foot",
        "toe": f"{S}ToeBase",
    }
    return {avatar[role]: (chain[i], h) for role, (i, h) in roles.items()}


def _head(tree: _SourceTree, pelvis: int, torso: int, top: int | None) -> tuple[int, str]:
    """The head and how: named, else the highest joint, or the one below it if that
    one is a "HeadTop_End"."""
    if top is not None:
        return top, "name"
    rest, depth, parents = tree.rest, tree.depth, tree.parents
    highest = max(tree.subtree[torso], key=lambda j: (rest[j, 2], -depth[j]))
    if END_MARKER.search(tree.names[highest]) and parents[highest] not in (pelvis, -1):
        return int(parents[highest]), "structure"
    return highest, "structure"


def _arm_branches(tree: _SourceTree, spine_path: list[int]) -> list[tuple[int, int]]:
    """Up to two (spine joint, branch) off the spine path that reach farthest, as arms."""
    rest, subtree = tree.rest, tree.subtree
    on_path = set(spine_path)
    offshoots = [(s, c) for s in spine_path[:-1] for c in tree.kids[s] if c not in on_path]
    reach = {
        c: float(np.linalg.norm(rest[subtree[c]] - rest[s], axis=1).max()) for s, c in offshoots
    }
    arm_kinds = ("collar", "shoulder", "upperarm", "forearm", "hand")
    named_arms = [
        (s, c) for s, c in offshoots if any(tree.kinds[j] in arm_kinds for j in subtree[c])
    ]
    pool = named_arms if len(named_arms) >= 2 else offshoots
    arms = sorted(pool, key=lambda sc: -reach[sc[1]])[:2]
    return [(s, c) for s, c in arms if reach[c] > 0.15 * tree.extent]


def _arm_joints(tree: _SourceTree, s: str, c: int) -> dict[str, tuple[int, str]]:
    """Avatar joint -> (source joint, how) along the arm branch ``c`` on side ``s``."""
    S = "Left" if s == "L" else "Right"
    rest, parents = tree.rest, tree.parents
    lengths = {c: 0.0}  # path length from the branch's first joint
    for j in sorted(tree.subtree[c])[1:]:
        bone = float(np.linalg.norm(rest[j] - rest[parents[j]]))
        lengths[j] = lengths[int(parents[j])] + bone
    tip = max(lengths, key=lambda j: (lengths[j], -tree.depth[j]))
    chain = [c, *_path(parents, c, tip)]
    roles = _arm_roles([tree.kinds[j] for j in chain], rest[chain])
    avatar = {
        "collar": f"{S}Shoulder",
        "arm": f"{S}Arm",
        "forearm": f"{S}ForeArm",
        "hand": f"{S}Hand",
    }
    return {avatar[role]: (chain[i], h) for role, (i, h) in roles.items()}


def _spine_and_neck(
    tree: _SourceTree, spine_path: list[int], arms: list[tuple[int, int]]
) -> dict[str, tuple[int, str]]:
    """Avatar spine and neck joint -> (source joint, how); the chest is where arms branch."""
    out: dict[str, tuple[int, str]] = {}
    chest_at = max((spine_path.index(s) for s, _ in arms), default=len(spine_path) - 2)
    spine = spine_path[: chest_at + 1]
    neck = spine_path[chest_at + 1 : -1]
    slots = {"Spine1": -1} if len(spine) == 1 else {"LowerBack": 0, "Spine1": -1}
    if len(spine) >= 3:
        slots["Spine"] = (len(spine) - 1) // 2
    for a, i in slots.items():
        if spine:
            out[a] = (spine[i], "name" if tree.kinds[spine[i]] == "spine" else "structure")
    for a, i in ({"Neck": 0, "Neck1": -1} if len(neck) >= 2 else {"Neck": 0}).items():
        if neck:
            out[a] = (neck[i], "name" if tree.kinds[neck[i]] == "neck" else "structure")
    return out


def match_skeleton(
    names: list[str] | tuple[str, ...],
    parents: np.ndarray,
    rest: np.ndarray,
    source: str = "skeleton",
) -> JointMatch:
    """Match a humanoid skeleton's joints to the avatar's, by name and structure.

    Args:
        names: J source joint names, parents before children.
        parents: (J,) parent indices, -1 for the root.
        rest: (J, 3) rest-pose joint positions in the avatar's axes (Z up, facing -Y,
            the character's left +X), any unit.
        source: the file, for error messages.

    Returns:
        The match: the avatar's pelvis, spine (LowerBack, Spine, Spine1), neck (Neck,
        Neck1), head, and per side hip joint, thigh, shin, foot, toe, collar, upper arm,
        forearm and hand, as far as the skeleton has them; ``align`` is the limbs found.

    Raises:
        SkeletonMatchError: naming the file, the avatar joints of
            :data:`~loosefit.motion.joint_names.REQUIRED` that nothing drives, the
            candidates found for each, and a map file line to write.
    """
    names = list(names)
    tree = _source_tree(
        names, np.asarray(parents, dtype=np.int64), np.asarray(rest, dtype=np.float64)
    )
    found: dict[str, int] = {}
    how: dict[str, str] = {}
    notes: list[str] = []

    def record(joints: dict[str, tuple[int, str]]) -> None:
        for a, (j, h) in joints.items():
            found[a], how[a] = j, h

    # 1. The pelvis.
    pelvis, how_pelvis = _find_pelvis(tree)
    if pelvis is None:
        raise_no_match(
            source,
            names,
            tree.parts,
            found,
            ["no joint branches into legs and a spine"],
            parents=tree.parents,
        )
    found["Hips"], how["Hips"] = pelvis, how_pelvis
    notes.append(f"pelvis: '{names[pelvis]}' ({how_pelvis})")
    unbranched = [
        names[j] for j in range(len(names)) if tree.kinds[j] == "root" and len(tree.kids[j]) == 1
    ]
    if how_pelvis == "structure" and unbranched:
        notes.append(f"'{unbranched[-1]}' is named as the pelvis but does not branch (no legs?)")
    body = tree.rest[tree.subtree[pelvis]]
    tree = replace(tree, extent=float(np.ptp(body, axis=0).max()))

    # 2. Its branches: the torso (reaching highest, or holding the head), the legs (low).
    torso, top = _torso(tree, pelvis)
    leg_side, how_side = _two_sides(_legs(tree, pelvis, torso), tree.subtree, tree.parts, tree.rest)
    found_legs = ", ".join(f"'{names[c]}' ({s})" for s, c in leg_side.items())
    if not found_legs:
        others = [c for c in tree.kids[pelvis] if c != torso]
        drop = max(
            (tree.rest[pelvis, 2] - tree.rest[tree.subtree[c], 2].min() for c in others),
            default=0.0,
        )
        found_legs = (
            f"none reach below the pelvis: of its {len(others)} other branches the lowest "
            f"reaches {drop:.3g} below it, a leg {0.25 * tree.extent:.3g} (a quarter of the "
            "body's size; axes wrong?)"
        )
    else:
        found_legs += f", sides by {how_side}"
    notes.append(f"torso: '{names[torso]}'; legs: {found_legs}")
    for s, c in leg_side.items():
        record(_leg_joints(tree, pelvis, s, c))

    # 3. The spine path, pelvis to head, and the arms that branch off it.
    head, how["Head"] = _head(tree, pelvis, torso, top)
    found["Head"] = head
    spine_path = _path(tree.parents, pelvis, head)
    arms = _arm_branches(tree, spine_path)
    arm_side, how_arm_side = _two_sides([c for _, c in arms], tree.subtree, tree.parts, tree.rest)
    notes.append(
        "arms: "
        + (", ".join(f"'{names[c]}' ({s})" for s, c in arm_side.items()) or "none")
        + f", sides by {how_arm_side}"
    )
    for s, c in arm_side.items():
        record(_arm_joints(tree, s, c))

    # 4. Spine and neck along the path; the chest is where the arms branch.
    record(_spine_and_neck(tree, spine_path, arms))

    missing = [a for a in REQUIRED if a not in found]
    if missing:
        raise_no_match(source, names, tree.parts, found, notes, missing, parents=tree.parents)
    joints = {a: names[found[a]] for a in _AVATAR_ORDER if a in found}
    jmap = JointMap("auto-matched", joints, tuple(a for a in LIMBS if a in joints))
    return JointMatch(jmap, {a: how[a] for a in joints}, tuple(notes))
