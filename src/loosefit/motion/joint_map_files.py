"""Joint map files: the one loosefit writes for a user to correct, and the checks a user's
map must pass against the skeleton it is for.

:func:`joint_map_template` writes what the matcher (:mod:`loosefit.motion.joint_match`)
found, or the names' guesses (:func:`~loosefit.motion.joint_names.guess_by_name`), as a YAML
map with a line per avatar joint; :func:`check_joint_map` refuses a map that cannot be the
skeleton's (joints out of their chain's order, a pelvis that is an empty root, a bending
joint skipped inside a limb) before anything is animated with it.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.motion.joint_match import JointMatch
from loosefit.motion.joint_names import TEMPLATE_PARTS, guess_by_name

_TEMPLATE_WORDS = {
    "UpLeg": "thigh",
    "Leg": "shin (knee)",
    "Foot": "ankle",
    "ToeBase": "toes",
    "Shoulder": "collar bone",
    "Arm": "upper arm",
    "ForeArm": "forearm (elbow)",
    "Hand": "wrist",
    "Hips": "pelvis, the legs' and spine's parent",
    "LowerBack": "lowest spine joint",
    "Spine1": "chest: the arms' parent",
    "Neck": "neck",
    "Head": "head",
}


def joint_map_template(
    names: list[str] | tuple[str, ...],
    match: JointMatch | None,
    source: str,
    axes: tuple[str, str] | None = None,
    parents: np.ndarray | None = None,
) -> str:
    """A joint map file (YAML) to correct by hand: what the matcher found, else guesses
    by name (:func:`guess_by_name`), and the joints nothing was found for as commented
    lines saying why, to fill in.

    Args:
        names: the source's joint names.
        match: the matcher's result, or None when it failed (then names alone).
        source: the motion file, for the header.
        axes: (up, forward) to write, or None.
        parents: (J,) the source's parent indices (the hierarchy the guesses check);
            None: read as a chain, parents before children.

    Returns:
        The file's text; :func:`~loosefit.motion.joint_maps.load_joint_map_file` reads it.
    """
    names = list(names)
    found = dict(match.joint_map.joints) if match is not None else {}
    notes: dict[str, str] = {}
    if parents is not None or match is None:
        taken = {s: a for a, s in found.items()}
        for a, (src, why) in guess_by_name(names, parents, taken).items():
            if a in found:
                continue
            if src is None:
                notes[a] = why
            else:
                found[a] = src
                notes[a] = why
    lines = [
        f"# Joint map for {Path(source).name}: 'avatar joint: source joint', one a line.",
        "# Correct the guesses, fill in the commented lines (remove the '# '), and pass",
        "# it as --joint-map FILE (or the motion spec joint-map:FILE:MOTION).",
        f"# The file's joints: {', '.join(names)}",
    ]
    order = (
        "Hips",
        "LowerBack",
        "Spine",
        "Spine1",
        "Neck",
        "Neck1",
        "Head",
        *(
            f"{S}{b}"
            for S in ("Left", "Right")
            for b in (
                "HipJoint",
                "UpLeg",
                "Leg",
                "Foot",
                "ToeBase",
                "Shoulder",
                "Arm",
                "ForeArm",
                "Hand",
            )
        ),
    )
    for a in order:
        a = {"LeftHipJoint": "LHipJoint", "RightHipJoint": "RHipJoint"}.get(a, a)
        bone = a.removeprefix("Left").removeprefix("Right")
        word = _TEMPLATE_WORDS.get(bone, "")
        how = match.how.get(a, "") if match is not None else ""
        if a in found:
            note = f"  # {how}" if how else (f"  # {notes[a]}" if a in notes else "")
            lines.append(f"{a}: {_yaml_name(found[a])}{note}")
        elif a in TEMPLATE_PARTS:
            why = f"; {notes[a]}" if a in notes else ""
            lines.append(f"# {a}: ?   # {word}{why}")
    if axes is not None:
        lines += [f"source_up: '{axes[0]}'", f"source_forward: '{axes[1]}'"]
    return "\n".join(lines) + "\n"


def _yaml_name(name: str) -> str:
    """A joint name as a YAML scalar (quoted when YAML would read it otherwise)."""
    plain = re.fullmatch(r"[A-Za-z_][A-Za-z0-9_.\- ]*[A-Za-z0-9_]|[A-Za-z_]", name)
    reserved = name.lower() in ("yes", "no", "on", "off", "true", "false", "null", "y", "n")
    return name if plain and not reserved else "'" + name.replace("'", "''") + "'"


# The avatar's chains, top to bottom: a map's joints along each must go down the source's.
_CHAINS = (
    ("Hips", "LHipJoint", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase"),
    ("Hips", "RHipJoint", "RightUpLeg", "RightLeg", "RightFoot", "RightToeBase"),
    ("Hips", "LowerBack", "Spine", "Spine1", "Neck", "Neck1", "Head"),
    ("Spine1", "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand"),
    ("Spine1", "RightShoulder", "RightArm", "RightForeArm", "RightHand"),
)
# A limb's segments: a joint skipped between the two may not bend (twist bones may).
_SEGMENTS = tuple(
    (f"{S}{a}", f"{S}{b}")
    for S in ("Left", "Right")
    for a, b in (("UpLeg", "Leg"), ("Leg", "Foot"), ("Arm", "ForeArm"), ("ForeArm", "Hand"))
)
BEND_SKIPPED_DEG = 20.0  # a skipped joint bending the limb further than this: a wrong map


def check_joint_map(
    joints: dict[str, str],
    names: list[str] | tuple[str, ...],
    parents: np.ndarray,
    positions: np.ndarray,
    source: str,
    map_name: str,
) -> None:
    """Refuse a joint map (a user's file) that cannot be this skeleton's.

    Along each avatar chain (hips to toes, hips to head, chest to hands) each mapped
    joint must lie below the one mapped before it in the source's hierarchy; the pelvis
    must be where the mapped legs and spine part (not a root of no geometry above it);
    and no joint skipped inside a limb segment (between the upper arm and the forearm,
    say) may bend the limb by more than :data:`BEND_SKIPPED_DEG` in the frames: it is a
    joint the map left out (``LeftArm: Shoulder_L`` over an ``UpperArm_L``).

    Args:
        joints: avatar joint -> source joint (every source joint among ``names``).
        names: J source joint names; parents: (J,) their parents, -1 for a root.
        positions: (T, J, 3) the joints' world positions over the frames (any axes).
        source: the motion file; map_name: the map (its file), for messages.

    Raises:
        LoosefitInputError: naming the map, the avatar joint, the source joints and
            what the file's hierarchy or frames show instead.
    """
    names = list(names)
    index = {n: i for i, n in enumerate(names)}
    parents = np.asarray(parents, dtype=np.int64)

    def above(top: int, j: int) -> bool:
        j = int(parents[j])
        while j >= 0 and j != top:
            j = int(parents[j])
        return j == top

    def refuse(avatar: str, found: str, hint: str) -> None:
        raise LoosefitInputError(
            map_name,
            avatar,
            f"a joint map that fits {Path(source).name}'s skeleton",
            found,
            hint=hint,
        )

    for chain in _CHAINS:
        mapped = [a for a in chain if a in joints]
        for a, b in zip(mapped, mapped[1:], strict=False):
            ja, jb = index[joints[a]], index[joints[b]]
            if not above(ja, jb):
                refuse(
                    b,
                    f"'{joints[b]}', which is not below {a} '{joints[a]}' in the file's hierarchy",
                    f"the joints below '{joints[a]}': "
                    f"{', '.join(names[k] for k in range(len(names)) if above(ja, k))[:300]}"
                    " (`loosefit inspect-motion FILE` prints the hierarchy)",
                )
    if "Hips" in joints:
        hips = index[joints["Hips"]]
        kids = [k for k in range(len(names)) if parents[k] == hips]
        others = [index[s] for a, s in joints.items() if a != "Hips"]
        if len(kids) == 1 and others and all(k == kids[0] or above(kids[0], k) for k in others):
            refuse(
                "Hips",
                f"'{joints['Hips']}', a joint with one child '{names[kids[0]]}' above "
                "every other mapped joint (no geometry of its own)",
                f"map Hips to the joint where the legs and the spine part, e.g. "
                f"'{names[kids[0]]}' or below it",
            )
    steps = np.linspace(0, len(positions) - 1, min(len(positions), 40)).round().astype(int)
    pos = np.asarray(positions, dtype=np.float64)[steps]  # (K, J, 3)
    for a, b in _SEGMENTS:
        if a not in joints or b not in joints:
            continue
        ja, jb = index[joints[a]], index[joints[b]]
        path = []
        j = int(parents[jb])
        while j >= 0 and j != ja:
            path.append(j)
            j = int(parents[j])
        for k in path:
            u, v = pos[:, k] - pos[:, ja], pos[:, jb] - pos[:, k]
            lu, lv = np.linalg.norm(u, axis=-1), np.linalg.norm(v, axis=-1)
            ok = (lu > 1e-6) & (lv > 1e-6)
            if not ok.any():
                continue
            cos = (u[ok] * v[ok]).sum(-1) / (lu[ok] * lv[ok])
            bend = float(np.degrees(np.arccos(np.clip(cos, -1, 1))).max())
            if bend > BEND_SKIPPED_DEG:
                refuse(
                    a,
                    f"'{joints[a]}' to {b} '{joints[b]}' passing over '{names[k]}', where "
                    f"the limb bends by up to {bend:.0f} degrees in the frames",
                    f"'{names[k]}' is a joint of the limb the map leaves out: map {a} to "
                    f"'{names[k]}' (and the joint above it to the one before), or "
                    "`loosefit inspect-motion FILE --write-joint-map MAP` for a map "
                    "filled in from what the matcher finds",
                )
