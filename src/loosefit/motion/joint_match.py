"""Matching any humanoid skeleton's joints to the avatar's, by name and by structure.

A BVH file from another tool names its joints its own way (``mixamorig:LeftUpLeg``,
``thigh_l``, ``left_hip``, ``UpperLeg_L``, ``lThigh``...). :func:`match_skeleton`
finds the avatar joints that retargeting needs in three steps:

1. **Names.** Each name is cut into a side and a body part
   (:func:`classify_joint_name`): a namespace (``xxx:``) and prefixes such as
   ``mixamorig``, ``joint_`` or ``Bip01`` are dropped; the side is ``Left``/``Right``,
   ``L``/``R``/``l``/``r`` before a capital or a separator, or ``_L``/``.L``/``_l``/
   ``Left`` at the end, in any case; the part comes from synonyms (``UpLeg``/
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

import re
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.motion.joint_maps import LIMBS, MAP_FILE_EXAMPLE, JointMap

# Dropped from the front of a name (after any namespace "xxx:").
_PREFIX = re.compile(
    r"^(mixamorig\d*[_:]?|joint[_\s.-]|jnt[_\s.-]|bip0?1[_\s.-]|def[_-]|b_|j_)", re.IGNORECASE
)
_SIDE_PATTERNS = (  # (regex, group holding the side); tried in order
    (re.compile(r"^(left|right)[_\s.-]?", re.IGNORECASE), 1),
    (re.compile(r"[_\s.-]?(left|right)$", re.IGNORECASE), 1),
    (re.compile(r"^([LRlr])(?:[_\s.-]|(?=[A-Z]))"), 1),
    (re.compile(r"[_\s.-]([LRlr])$"), 1),
    (re.compile(r"(?<=[a-z])([LR])$"), 1),
)
# Body part of a name's base (lower case, letters only), sided and unsided.
_UNSIDED_PARTS = {
    **dict.fromkeys(("hips", "hip", "pelvis", "root"), "root"),
    **dict.fromkeys(("spine", "chest", "upperchest", "abdomen", "abdomenlower",
                     "abdomenupper", "lowerback", "upperback", "torso", "back"), "spine"),
    **dict.fromkeys(("neck", "necklower", "neckupper"), "neck"),
    "head": "head",
}  # fmt: skip
_SIDED_PARTS = {
    **dict.fromkeys(("collar", "clavicle"), "collar"),
    "shoulder": "shoulder",  # a collar or an upper arm, by what follows
    **dict.fromkeys(("arm", "upperarm", "uparm", "shldr", "shldrbend"), "upperarm"),
    **dict.fromkeys(("forearm", "lowerarm", "elbow", "forearmbend"), "forearm"),
    **dict.fromkeys(("hand", "wrist"), "hand"),
    **dict.fromkeys(("hipjoint", "buttock"), "hipjoint"),
    "hip": "hip",  # a thigh, or the hip joint before one
    **dict.fromkeys(("upleg", "upperleg", "thigh", "thighbend"), "thigh"),
    **dict.fromkeys(("leg", "lowerleg", "shin", "calf", "knee"), "shin"),
    **dict.fromkeys(("foot", "ankle"), "foot"),
    **dict.fromkeys(("toe", "toes", "toebase", "ball"), "toe"),
}  # fmt: skip
_END_MARKER = re.compile(r"end|top|nub|tip|site", re.IGNORECASE)

# The avatar joints a skeleton must drive, and what each is called in messages.
_LEG = {"UpLeg": "thigh", "Leg": "shin", "Foot": "foot"}
_ARM = {"Arm": "upper arm", "ForeArm": "forearm", "Hand": "hand"}
REQUIRED = ("Hips",) + tuple(f"{S}{b}" for S in ("Left", "Right") for b in (*_LEG, *_ARM))
_PART_WORDS = {  # the part a missing avatar joint needs -> names that would have matched
    "root": "Hips, Pelvis, Root", "thigh": "UpLeg, Thigh, UpperLeg, Hip",
    "shin": "Leg, Shin, Calf, LowerLeg, Knee", "foot": "Foot, Ankle",
    "upperarm": "Arm, UpperArm, Shoulder, Shldr", "forearm": "ForeArm, LowerArm, Elbow",
    "hand": "Hand, Wrist",
}  # fmt: skip


@dataclass(frozen=True)
class NameParts:
    """What a joint's name says: its side ("L", "R" or None) and body part (or None)."""

    side: str | None
    part: str | None
    base: str  # the name without namespace, prefix, side and digits, lower case


def classify_joint_name(name: str) -> NameParts:
    """Side and body part of a joint name (see the module's docstring for the rules).

    ``classify_joint_name("mixamorig:LeftUpLeg")`` is ``NameParts("L", "thigh", "upleg")``;
    ``"spine_02"`` is ``(None, "spine", "spine")``; a finger such as ``LeftHandIndex1``
    has no part (``base="handindex"``).
    """
    text = name.rsplit(":", 1)[-1].strip()
    text = _PREFIX.sub("", text) or text
    side = None
    for pattern, group in _SIDE_PATTERNS:
        m = pattern.search(text)
        if m and len(text) > len(m.group(0)):
            side = m.group(group)[0].upper()
            text = text[: m.start()] + text[m.end() :]
            break
    base = re.sub(r"[^a-z]", "", re.sub(r"\d+$", "", re.sub(r"[^a-z0-9]", "", text.lower())))
    part = (_SIDED_PARTS if side else _UNSIDED_PARTS).get(base)
    if part is None and side is None and base in _SIDED_PARTS and base != "hip":
        part = _SIDED_PARTS[base]  # a limb without a side: structure decides which
    return NameParts(side, part, base)


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
    if _END_MARKER.search(tree.names[highest]) and parents[highest] not in (pelvis, -1):
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
        LoosefitInputError: naming the file, the avatar joints of :data:`REQUIRED` that
            nothing drives, the candidates found for each, and a map file line to write.
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
        _fail(
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
        _fail(source, names, tree.parts, found, notes, missing, tree.parents)
    joints = {a: names[found[a]] for a in _AVATAR_ORDER if a in found}
    jmap = JointMap("auto-matched", joints, tuple(a for a in LIMBS if a in joints))
    return JointMatch(jmap, {a: how[a] for a in joints}, tuple(notes))


class SkeletonMatchError(LoosefitInputError):
    """The matcher found no humanoid in a skeleton (a :class:`LoosefitInputError`).

    Attributes:
        missing: the avatar joints of :data:`REQUIRED` that nothing drives.
        notes: what the matcher decided on the way (pelvis, torso, legs, arms).
        details: for each missing joint, the joints named like it (or that none are).
        guesses: avatar joint -> a source joint named like it (for a map file's lines).
    """

    def __init__(self, *args, missing=(), notes=(), guesses=None, details=(), **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.missing = tuple(missing)
        self.notes = tuple(notes)
        self.guesses = dict(guesses or {})
        self.details = tuple(details)

    def __reduce__(self):
        return _rebuild_match_error, (
            (self.source, self.field, self.expected, self.found, self.hint),
            self.missing,
            self.notes,
            self.guesses,
            self.details,
        )


def _rebuild_match_error(args, missing, notes, guesses, details) -> SkeletonMatchError:
    return SkeletonMatchError(*args, missing=missing, notes=notes, guesses=guesses, details=details)


MATCH_EXPECTED = (
    "a humanoid skeleton the joint matcher can map: a pelvis with two legs (thigh, shin, "
    "foot) and a spine with two arms (upper arm, forearm, hand)"
)


def map_file_hint(source: str, guesses: dict[str, str] | None = None) -> str:
    """What to write in a joint map for a skeleton the matcher cannot map: the lines the
    names suggest (``guesses``, avatar joint -> source joint) and where to pass the file."""
    lines = ", ".join(f"'{a}: {s}'" for a, s in (guesses or {}).items())
    example = f"({lines} by the names; check them)" if lines else f"e.g. '{MAP_FILE_EXAMPLE}'"
    return (
        "write a joint map file (YAML or TOML), one line 'avatar joint: your joint' per "
        f"joint {example}, and pass --joint-map FILE (the motion spec "
        "joint-map:FILE:CLIP.bvh elsewhere); "
        f"{joint_map_template_hint(source)}; a skeleton not Y up and facing +Z: "
        "source_up and source_forward in a map file"
    )


def _fail(
    source: str,
    names: list[str],
    parts: list[NameParts],
    found: dict[str, int],
    notes: list[str],
    missing: list[str] | None = None,
    parents: np.ndarray | None = None,
) -> None:
    """Raise the error for a skeleton the matcher cannot map."""
    missing = missing or list(REQUIRED)
    details = []
    for a in missing:
        side = "L" if a.startswith("Left") else "R" if a.startswith("Right") else None
        bone = a.removeprefix("Left").removeprefix("Right")
        part = {"Hips": "root", **{k: v.replace(" ", "") for k, v in {**_LEG, **_ARM}.items()}}
        want = {
            "root": ("root",),
            "thigh": ("thigh", "hip"),
            "shin": ("shin",),
            "foot": ("foot",),
            "upperarm": ("upperarm", "shoulder"),
            "forearm": ("forearm",),
            "hand": ("hand",),
        }[part[bone]]
        cands = [
            n
            for n, p in zip(names, parts, strict=True)
            if p.part in want and (side is None or p.side in (side, None))
        ]
        what = (
            f"candidates {cands[:4]}" if cands else f"no joint named like {_PART_WORDS[part[bone]]}"
        )
        details.append(f"{a}: {what}")
    guesses = {}
    if parents is not None:
        named = guess_by_name(names, parents, {names[j]: a for a, j in found.items()})
        guesses = {a: named[a][0] for a in missing if a in named}
    raise SkeletonMatchError(
        source,
        "HIERARCHY",
        MATCH_EXPECTED,
        f"nothing for {missing} ({'; '.join(details)}; {'; '.join(notes)}; "
        f"its joints: {', '.join(names[:40])}{'...' if len(names) > 40 else ''})",
        hint=map_file_hint(source, guesses),
        missing=missing,
        notes=notes,
        guesses=guesses,
        details=details,
    )


# What a template line guesses for each avatar joint from the names alone: (side, parts).
TEMPLATE_PARTS = {
    "Hips": (None, ("root",)), "LowerBack": (None, ("spine",)), "Spine1": (None, ("spine",)),
    "Neck": (None, ("neck",)), "Head": (None, ("head",)),
    **{f"{S}{bone}": (S[0], parts) for S in ("Left", "Right") for bone, parts in (
        ("UpLeg", ("thigh", "hip")), ("Leg", ("shin",)), ("Foot", ("foot",)),
        ("ToeBase", ("toe",)), ("Shoulder", ("collar",)), ("Arm", ("upperarm", "shoulder")),
        ("ForeArm", ("forearm",)), ("Hand", ("hand",)))},
}  # fmt: skip


def guess_by_name(
    names: list[str], parents: np.ndarray | None, taken: dict[str, str] | None = None
) -> dict[str, tuple[str | None, str]]:
    """Avatar joint -> (source joint or None, why), from the names and the hierarchy alone.

    For the joints a map file must have (:data:`TEMPLATE_PARTS`): the first source joint
    named as that part on that side (the chest: the last spine joint), not yet ``taken``
    (source joint -> avatar joint). A sided ``Shoulder`` is the collar when an upper arm
    of that side lies below it, else the upper arm; a sided ``Hip`` is the hip joint when
    a thigh lies below it. The pelvis must branch (into legs and a spine): a joint named
    so with a single child (a root of no geometry of its own above the hips) is passed
    over, and when no named joint branches, the first joint that does is taken.

    Args:
        names: J source joint names, parents before children.
        parents: (J,) parent indices, -1 for a root; None: the hierarchy is unknown (names
            alone: a Shoulder is an upper arm, a Hip a thigh, any pelvis is taken).
        taken: source joints already mapped, left out.

    Returns:
        For each avatar joint guessed or refused: (the source joint, "guessed by name" or
        "by structure"), or (None, why none was taken).
    """
    parts = [classify_joint_name(n) for n in names]
    kids: list[list[int]] = [[] for _ in names]
    for j, p in enumerate(parents if parents is not None else []):
        if p >= 0:
            kids[p].append(j)
    below: list[set[int]] = [set() for _ in names]
    for j in range(len(names) - 1, -1, -1):
        for c in kids[j]:
            below[j] |= {c} | below[c]
    role = []  # what each joint is taken for
    for j, p in enumerate(parts):
        part = p.part
        if part == "shoulder":
            has_arm = any(parts[k].part == "upperarm" and parts[k].side == p.side for k in below[j])
            part = "collar" if has_arm else "upperarm"
        elif part == "hip" and p.side:
            has_thigh = any(parts[k].part == "thigh" and parts[k].side == p.side for k in below[j])
            part = "hipjoint" if has_thigh else "thigh"
        role.append(part)
    used = set(taken or {})
    out: dict[str, tuple[str | None, str]] = {}
    for a, (side, want) in TEMPLATE_PARTS.items():
        cands = [
            j
            for j, p in enumerate(parts)
            if role[j] in want and p.side == side and names[j] not in used
        ]
        if a == "Spine1" and cands:  # the chest is the last spine joint, the lower back the first
            cands = cands[-1:]
        if a == "Hips" and parents is not None:
            empty = [j for j in cands if len(kids[j]) < 2]
            cands = [j for j in cands if len(kids[j]) >= 2]
            if not cands:
                first = next((j for j in range(len(names)) if len(kids[j]) >= 2), None)
                if first is not None and names[first] not in used:
                    out[a] = (names[first], "by structure: the first joint that branches")
                    used.add(names[first])
                    continue
                if empty:
                    out[a] = (
                        None,
                        f"'{names[empty[0]]}' is named so but does not branch "
                        "into legs and a spine (no geometry of its own)",
                    )
                continue
        if cands:
            out[a] = (names[cands[0]], "guessed by name")
            used.add(names[cands[0]])
    return out


def joint_map_template_hint(source: str) -> str:
    """The command that writes a filled-in joint map for a motion file, for error hints."""
    return (
        f"`loosefit inspect-motion {Path(source).name} --write-joint-map my_map.yaml` "
        "writes one filled in with what was found and guessed by name, to correct and "
        "pass as --joint-map my_map.yaml"
    )
