"""What a joint's name says: its side and body part, and the avatar joint it suggests.

:func:`classify_joint_name` cuts a name into a side and a body part (the rules are step 1
of :mod:`loosefit.motion.joint_match`); :func:`guess_by_name` proposes, from the names and
the hierarchy alone, a source joint for each avatar joint a joint map needs
(:data:`TEMPLATE_PARTS`), for a map file's template and for the matcher's error hints.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

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
END_MARKER = re.compile(r"end|top|nub|tip|site", re.IGNORECASE)

# The avatar joints a skeleton must drive, and what each is called in messages.
LEG_BONES = {"UpLeg": "thigh", "Leg": "shin", "Foot": "foot"}
ARM_BONES = {"Arm": "upper arm", "ForeArm": "forearm", "Hand": "hand"}
REQUIRED = ("Hips",) + tuple(f"{S}{b}" for S in ("Left", "Right") for b in (*LEG_BONES, *ARM_BONES))
PART_WORDS = {  # the part a missing avatar joint needs -> names that would have matched
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
    """Side and body part of a joint name (the rules: :mod:`loosefit.motion.joint_match`).

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
