"""What the joint matcher says when it finds no humanoid in a skeleton.

:class:`SkeletonMatchError` names the avatar joints nothing drives, the joints named like
each, and the lines a joint map file would need (:func:`map_file_hint`, from
:func:`~loosefit.motion.joint_names.guess_by_name`); :func:`raise_no_match` builds it for
:func:`~loosefit.motion.joint_match.match_skeleton`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.motion.joint_maps import MAP_FILE_EXAMPLE
from loosefit.motion.joint_names import (
    ARM_BONES,
    LEG_BONES,
    PART_WORDS,
    REQUIRED,
    NameParts,
    guess_by_name,
)


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


def raise_no_match(
    source: str,
    names: list[str],
    parts: list[NameParts],
    found: dict[str, int],
    notes: list[str],
    missing: list[str] | None = None,
    *,
    parents: np.ndarray | None = None,
) -> None:
    """Raise the error for a skeleton the matcher cannot map."""
    missing = missing or list(REQUIRED)
    details = []
    for a in missing:
        side = "L" if a.startswith("Left") else "R" if a.startswith("Right") else None
        bone = a.removeprefix("Left").removeprefix("Right")
        part = {
            "Hips": "root",
            **{k: v.replace(" ", "") for k, v in {**LEG_BONES, **ARM_BONES}.items()},
        }
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
            f"candidates {cands[:4]}" if cands else f"no joint named like {PART_WORDS[part[bone]]}"
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


def joint_map_template_hint(source: str) -> str:
    """The command that writes a filled-in joint map for a motion file, for error hints."""
    return (
        f"`loosefit inspect-motion {Path(source).name} --write-joint-map my_map.yaml` "
        "writes one filled in with what was found and guessed by name, to correct and "
        "pass as --joint-map my_map.yaml"
    )
