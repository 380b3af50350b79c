"""Read Biovision Hierarchy (BVH) motion capture files.

The data stays in the file's own frame (usually Y up, facing +Z): converting to
loosefit's Z-up world is the retargeting step's job. Lengths are converted to
metres (see :func:`read_bvh` for the unit rule).

Quick start::

    clip = read_bvh("61_01.bvh")
    positions, world_rotations = forward_kinematics(clip)  # (T, J, 3), (T, J, 3, 3)

(:func:`~loosefit.motion.skeleton_clip.forward_kinematics` and the clip's other
kinematics live in :mod:`loosefit.motion.skeleton_clip`.)

BVH semantics used here:

* A joint's local rotation is the product of its rotation channels in the order
  they are listed: ``Zrotation Xrotation Yrotation`` with values ``(a, b, c)``
  gives ``Rz(a) @ Rx(b) @ Ry(c)`` (column vectors, degrees in the file).
* A joint's local translation is its ``OFFSET`` plus its position channels
  (``position_channels="add"``, the default), or the position channels replace
  the offset on the axes they cover (``"replace"``), for exporters that write
  six channels on every joint with the offset repeated in them.
* World transforms: ``G_j = G_parent @ [R_j | t_j]`` and ``G_root = [R_0 | t_0]``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.geometry.rotations import euler_to_matrix
from loosefit.motion.skeleton_clip import BvhClip, body_extent

_CHANNEL_NAMES = {
    name.lower(): name
    for name in (
        "Xposition",
        "Yposition",
        "Zposition",
        "Xrotation",
        "Yrotation",
        "Zrotation",
    )
}

_UNIT_SCALES = {"m": 1.0, "cm": 0.01, "mm": 0.001}
BVH_UNITS = ("auto", *_UNIT_SCALES)  # what read_bvh's ``units`` takes

# "auto" units: a rest skeleton whose largest bounding-box side exceeds this many
# file units is taken to be in centimetres, and above the second bound in millimetres.
AUTO_CM_ABOVE = 10.0
AUTO_MM_ABOVE = 500.0


# --------------------------------------------------------------------------- parsing


class _Lines:
    """Cursor over the whitespace-split lines of the HIERARCHY section."""

    def __init__(self, path: Path, lines: list[list[str]], first_lineno: int) -> None:
        self.path = path
        self.lines = lines  # tokens per line
        self.first_lineno = first_lineno  # 1-based file line number of lines[0]
        self.i = 0  # current line
        self.k = 0  # current token in the line

    def lineno(self) -> int:
        return self.first_lineno + min(self.i, len(self.lines) - 1)

    def _skip_empty(self) -> None:
        while self.i < len(self.lines) and self.k >= len(self.lines[self.i]):
            self.i += 1
            self.k = 0

    def peek(self) -> str | None:
        self._skip_empty()
        return self.lines[self.i][self.k] if self.i < len(self.lines) else None

    def next(self, field: str, expected: str) -> str:
        tok = self.peek()
        if tok is None:
            raise LoosefitInputError(
                self.path, field, expected, "end of the HIERARCHY section (missing '}' or MOTION)"
            )
        self.k += 1
        return tok

    def rest_of_line(self) -> list[str]:
        """The remaining tokens of the current line (possibly none); moves to the next line."""
        rest = self.lines[self.i][self.k :] if self.i < len(self.lines) else []
        self.i += 1
        self.k = 0
        return rest


@dataclass
class _Skeleton:
    names: list[str] = field(default_factory=list)
    parents: list[int] = field(default_factory=list)
    offsets: list[tuple[float, float, float]] = field(default_factory=list)
    channels: list[tuple[str, ...]] = field(default_factory=list)
    end_offsets: dict[int, tuple[float, float, float]] = field(default_factory=dict)
    lines: dict[str, int] = field(default_factory=dict)  # joint name -> line of its declaration


def _parse_floats(path: Path, field_name: str, tokens: list[str], n: int, line: int) -> tuple:
    if len(tokens) != n:
        raise LoosefitInputError(
            path, field_name, f"{n} numbers", f"{len(tokens)} values {tokens} on line {line}"
        )
    try:
        values = tuple(float(t) for t in tokens)
    except ValueError:
        raise LoosefitInputError(
            path, field_name, f"{n} numbers", f"{tokens} on line {line}"
        ) from None
    if not all(np.isfinite(values)):
        raise LoosefitInputError(path, field_name, "finite numbers", f"{tokens} on line {line}")
    return values


def _parse_joint(cur: _Lines, skel: _Skeleton, parent: int, keyword: str) -> None:
    """Parse ``ROOT|JOINT name { OFFSET ... CHANNELS ... children }`` (keyword consumed)."""
    path = cur.path
    line = cur.lineno()
    rest = cur.rest_of_line()
    opened = bool(rest) and rest[-1] == "{"
    name = " ".join(rest[:-1] if opened else rest)
    if not name:
        raise LoosefitInputError(path, keyword, "a joint name", f"nothing on line {line}")
    if name in skel.lines:
        raise LoosefitInputError(
            path,
            f"{keyword} {name}",
            "unique joint names",
            f"'{name}' declared on line {skel.lines[name]} and again on line {line}",
        )
    where = f"joint '{name}'"
    if not opened:
        tok = cur.next(f"{where} braces", "'{'")
        if tok != "{":
            raise LoosefitInputError(
                path, f"{where} braces", "'{'", f"{tok!r} on line {cur.lineno()}"
            )
    index = len(skel.names)
    skel.names.append(name)
    skel.parents.append(parent)
    skel.offsets.append(None)  # type: ignore[arg-type]  # set when OFFSET is read
    skel.channels.append(())
    skel.lines[name] = line

    while True:
        tok = cur.next(f"{where} braces", f"'}}' closing joint '{name}' opened on line {line}")
        tok_line = cur.lineno()
        if tok == "}":
            break
        if tok == "OFFSET":
            skel.offsets[index] = _parse_floats(
                path, f"{where} OFFSET", cur.rest_of_line(), 3, tok_line
            )
        elif tok == "CHANNELS":
            skel.channels[index] = _parse_channels(path, where, cur.rest_of_line(), tok_line)
        elif tok == "JOINT":
            _parse_joint(cur, skel, index, "JOINT")
        elif tok == "End":
            if cur.peek() == "Site":
                cur.next("End Site", "'Site'")
            _parse_end_site(cur, skel, index, where)
        else:
            raise LoosefitInputError(
                path,
                f"{where} contents",
                "OFFSET, CHANNELS, JOINT, End Site or '}'",
                f"{tok!r} on line {tok_line}",
            )
    if skel.offsets[index] is None:
        raise LoosefitInputError(
            path, f"{where} OFFSET", "an OFFSET line", f"none in the joint (line {line})"
        )


def _parse_channels(path: Path, where: str, tokens: list[str], line: int) -> tuple[str, ...]:
    field_name = f"{where} CHANNELS"
    if not tokens:
        raise LoosefitInputError(path, field_name, "a channel count", f"nothing on line {line}")
    try:
        count = int(tokens[0])
    except ValueError:
        raise LoosefitInputError(
            path, field_name, "an integer channel count", f"{tokens[0]!r} on line {line}"
        ) from None
    names = tokens[1:]
    if count != len(names):
        raise LoosefitInputError(
            path,
            field_name,
            f"{count} channel names (the count written)",
            f"{len(names)} names {names} on line {line}",
        )
    out = []
    for n in names:
        canonical = _CHANNEL_NAMES.get(n.lower())
        if canonical is None:
            raise LoosefitInputError(
                path,
                field_name,
                "channel names among Xposition Yposition Zposition Xrotation Yrotation Zrotation",
                f"{n!r} on line {line}",
            )
        if canonical in out:
            raise LoosefitInputError(
                path, field_name, "each channel at most once", f"{canonical} twice on line {line}"
            )
        out.append(canonical)
    return tuple(out)


def _parse_end_site(cur: _Lines, skel: _Skeleton, index: int, where: str) -> None:
    path = cur.path
    line = cur.lineno()
    field_name = f"{where} End Site"
    if index in skel.end_offsets:
        raise LoosefitInputError(
            path, field_name, "at most one End Site per joint", f"a second one on line {line}"
        )
    tok = cur.next(field_name, "'{'")
    if tok != "{":
        raise LoosefitInputError(path, field_name, "'{'", f"{tok!r} on line {cur.lineno()}")
    offset = None
    while True:
        tok = cur.next(field_name, f"'}}' closing the End Site opened on line {line}")
        if tok == "}":
            break
        if tok != "OFFSET":
            raise LoosefitInputError(
                path, field_name, "OFFSET or '}'", f"{tok!r} on line {cur.lineno()}"
            )
        tok_line = cur.lineno()
        offset = _parse_floats(path, f"{field_name} OFFSET", cur.rest_of_line(), 3, tok_line)
    if offset is None:
        raise LoosefitInputError(path, f"{field_name} OFFSET", "an OFFSET line", "none")
    skel.end_offsets[index] = offset


def _parse_hierarchy(path: Path, lines: list[str]) -> _Skeleton:
    """Parse lines ``[0, motion_line)`` of the file into a skeleton."""
    tokens = [ln.split() for ln in lines]
    first = next((i for i, t in enumerate(tokens) if t), None)
    if first is None or tokens[first][0] != "HIERARCHY":
        found = " ".join(tokens[first]) if first is not None else "an empty header"
        raise LoosefitInputError(path, "HIERARCHY", "the file to start with HIERARCHY", found)
    cur = _Lines(path, tokens, 1)
    cur.i, cur.k = first, 1
    skel = _Skeleton()
    tok = cur.peek()
    if tok != "ROOT":
        raise LoosefitInputError(
            path,
            "ROOT",
            "a ROOT joint after HIERARCHY",
            f"{tok!r} on line {cur.lineno()}" if tok else "nothing before MOTION",
        )
    cur.next("ROOT", "ROOT")
    _parse_joint(cur, skel, -1, "ROOT")
    tok = cur.peek()
    if tok is not None:
        if tok == "}":
            raise LoosefitInputError(
                path,
                "HIERARCHY braces",
                "balanced braces: nothing after the ROOT joint's closing '}'",
                f"an extra '}}' on line {cur.lineno()}",
            )
        if tok == "ROOT":
            second = " ".join(cur.lines[cur.i][cur.k + 1 :]).rstrip("{ ")
            raise LoosefitInputError(
                path,
                "ROOT",
                f"one ROOT per file (the skeleton under ROOT '{skel.names[0]}')",
                f"a second ROOT {second!r} on line {cur.lineno()}",
                hint="a file with two skeletons: keep the dancer's and remove the other",
            )
        raise LoosefitInputError(
            path,
            "MOTION",
            "a MOTION line after the ROOT joint's closing '}' (one ROOT per file)",
            f"{tok!r} on line {cur.lineno()}",
        )
    return skel


_FRAMES_RE = re.compile(r"^\s*Frames\s*:\s*(\S*)\s*$")
_FRAME_TIME_RE = re.compile(r"^\s*Frame\s+Time\s*:\s*(\S*)\s*$")


def _parse_motion_header(path: Path, lines: list[str], start: int) -> tuple[int, float, int]:
    """Read ``Frames:`` and ``Frame Time:`` after MOTION; return them and the first data line."""
    i = start
    values = []
    for label, regex in (("Frames", _FRAMES_RE), ("Frame Time", _FRAME_TIME_RE)):
        while i < len(lines) and not lines[i].strip():
            i += 1
        match = regex.match(lines[i]) if i < len(lines) else None
        if match is None:
            found = repr(lines[i].strip()[:60]) if i < len(lines) else "end of file"
            raise LoosefitInputError(
                path, f"MOTION/{label}", f"a '{label}: <number>' line", f"{found} (line {i + 1})"
            )
        values.append((match.group(1), i + 1))
        i += 1
    (frames_txt, frames_line), (time_txt, time_line) = values
    try:
        frames = int(frames_txt)
    except ValueError:
        frames = -1
    if frames < 1:
        raise LoosefitInputError(
            path, "MOTION/Frames", "a positive integer", f"{frames_txt!r} on line {frames_line}"
        )
    try:
        frame_time = float(time_txt)
    except ValueError:
        frame_time = float("nan")
    if not (np.isfinite(frame_time) and frame_time > 0):
        raise LoosefitInputError(
            path,
            "MOTION/Frame Time",
            "a positive number of seconds",
            f"{time_txt!r} on line {time_line}",
        )
    return frames, frame_time, i


def _parse_frames(
    path: Path, lines: list[str], start: int, frames: int, width: int, labels: list[str]
) -> np.ndarray:
    """The frame lines as a (frames, width) float64 array, each value checked."""
    rows = [(i + 1, ln.split()) for i, ln in enumerate(lines[start:], start) if ln.strip()]
    counts = np.array([len(r) for _, r in rows], dtype=np.int64)
    total = int(counts.sum())
    if len(rows) == frames:
        bad = np.flatnonzero(counts != width)
        if len(bad):
            f = int(bad[0])
            raise LoosefitInputError(
                path,
                f"MOTION frame {f}",
                f"{width} values (one per channel)",
                f"{counts[f]} values on line {rows[f][0]}",
                hint="frames counted from 0",
            )
    elif total != frames * width:  # frames wrapped over several lines are accepted
        raise LoosefitInputError(
            path,
            "MOTION/Frames",
            f"{frames} frame lines of {width} values (as 'Frames: {frames}' says)",
            f"{len(rows)} frame lines with {total} values in all",
            hint="the file may be truncated" if total < frames * width else None,
        )
    flat = [tok for _, r in rows for tok in r]
    try:
        data = np.array(flat, dtype=np.float64)
    except ValueError:
        for f, (lineno, r) in enumerate(rows):
            for c, tok in enumerate(r):
                try:
                    float(tok)
                except ValueError:
                    where = f"MOTION frame {f}" if len(rows) == frames else f"MOTION line {lineno}"
                    raise LoosefitInputError(
                        path,
                        where,
                        "numeric values",
                        f"{tok!r} at value {c} on line {lineno}",
                        hint="frames counted from 0",
                    ) from None
        raise
    data = data.reshape(frames, width)  # (T, C)
    bad = ~np.isfinite(data)
    if bad.any():
        f, c = (int(v) for v in np.argwhere(bad)[0])
        line = rows[f][0] if len(rows) == frames else "?"
        raise LoosefitInputError(
            path,
            f"MOTION frame {f}",
            "finite values",
            f"{data[f, c]} for {labels[c]} on line {line} ({int(bad.sum())} non-finite in all)",
            hint="frames counted from 0",
        )
    return data


# --------------------------------------------------------------------------- reading


def _units_scale(
    path: Path, offsets: np.ndarray, end_offsets: dict, parents: list[int], units: str
) -> float:
    """Metres per file unit: the given unit's, or for "auto" guessed from the size of the
    body at rest (:func:`~loosefit.motion.skeleton_clip.body_joints`: a capture's start
    position baked into the hips' OFFSET below an empty root does not make the dancer
    larger)."""
    if units in _UNIT_SCALES:
        return _UNIT_SCALES[units]
    if units != "auto":
        raise LoosefitInputError(path, "units", "one of 'm', 'cm', 'mm', 'auto'", repr(units))
    extent = body_extent(np.asarray(parents), offsets, end_offsets)
    if extent > AUTO_MM_ABOVE:
        return 0.001
    if extent > AUTO_CM_ABOVE:
        return 0.01
    return 1.0


def _bones_from_channels(
    parents: np.ndarray, offsets: np.ndarray, channels: list[tuple[str, ...]], data: np.ndarray
) -> tuple[np.ndarray, list[int]]:
    """Offsets with each bone that lives in the frames alone filled in.

    A rig may write every OFFSET as zeros and each joint's bone in its position channels
    (the skeleton's shape exists only in the frames). A joint below the root with all
    three position channels, a zero OFFSET and channels that are not zero gets the
    channels' median over the frames as its OFFSET: its zero pose, for the matcher, the
    units guess and the calibration.

    Args:
        parents: (J,) parent indices; offsets: (J, 3) the file's OFFSETs, file units.
        channels: per joint, its channel names; data: (T, C) the frames' values.

    Returns:
        (J, 3) offsets, and the joints whose offsets came from the frames.
    """
    out = offsets.copy()
    filled = []
    col = 0
    for j, chans in enumerate(channels):
        cols = {name[0]: col + i for i, name in enumerate(chans) if name.endswith("position")}
        col += len(chans)
        if parents[j] < 0 or len(cols) < 3 or np.abs(offsets[j]).max() > 1e-9:
            continue
        values = data[:, [cols["X"], cols["Y"], cols["Z"]]]  # (T, 3)
        if len(values) and np.linalg.norm(values, axis=1).max() > 1e-9:
            out[j] = np.median(values, axis=0)
            filled.append(j)
    return out, filled


def read_bvh(
    path: str | Path,
    units: Literal["auto", "m", "cm", "mm"] = "auto",
    scale: float | None = None,
    position_channels: Literal["add", "replace"] = "add",
) -> BvhClip:
    """Read a BVH file into a :class:`BvhClip`, lengths in metres.

    Accepts any rotation order per joint, position channels on any joint (in any
    order, interleaved with rotations), any frame time, CRLF line endings, tabs,
    trailing whitespace and frames wrapped over several lines.

    Units: the file's lengths are multiplied by ``scale`` when it is given;
    otherwise by the factor for ``units``. ``"auto"`` measures the rest skeleton
    (joints and End Sites at zero rotation): if its largest bounding-box side is
    above 500 file units the file is taken to be in millimetres, above 10 in
    centimetres, else in metres (no person is 10 m tall, nor 10 cm). Files in
    other units (e.g. inches) need an explicit ``scale``.

    Args:
        path: the ``.bvh`` file.
        units: the file's length unit, or ``"auto"`` to guess it (see above).
        scale: an explicit factor from file units to metres; overrides ``units``.
        position_channels: ``"add"`` (local translation = OFFSET + channels) or
            ``"replace"`` (channels replace the OFFSET on the axes they cover).

    Returns:
        The clip, in the file's own axes (BVH is usually Y up).

    Raises:
        LoosefitInputError: for any malformed content, naming the file, the field
            (e.g. ``joint 'lShin' CHANNELS``, ``MOTION frame 17``) and the line.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8", errors="strict")
    except UnicodeDecodeError:
        text = path.read_text(encoding="latin-1")
    except OSError as exc:
        raise LoosefitInputError(path, "<file>", "a readable BVH file", str(exc)) from exc
    lines = text.removeprefix("\ufeff").splitlines()  # drops a BOM; handles \n, \r\n, \r

    # 1. Split at the MOTION line.
    motion_line = next((i for i, ln in enumerate(lines) if ln.strip() == "MOTION"), None)
    if motion_line is None:
        # Report what is missing first: the hierarchy, then the motion.
        _parse_hierarchy(path, lines)
        raise LoosefitInputError(path, "MOTION", "a MOTION section", "none in the file")

    # 2. The skeleton.
    skel = _parse_hierarchy(path, lines[:motion_line])
    parents = np.asarray(skel.parents, dtype=np.int64)  # (J,)
    raw_offsets = np.asarray(skel.offsets, dtype=np.float64)  # (J, 3)
    J = len(skel.names)

    # 3. The frames.
    frames, frame_time, data_start = _parse_motion_header(path, lines, motion_line + 1)
    labels = [  # "joint 'lShin' Zrotation" for each column
        f"joint '{name}' {c}"
        for name, chans in zip(skel.names, skel.channels, strict=True)
        for c in chans
    ]
    data = _parse_frames(path, lines, data_start, frames, len(labels), labels)  # (T, C)

    # 4. Bones that live in the frames alone, then units.
    file_offsets = raw_offsets
    raw_offsets, from_frames = _bones_from_channels(parents, raw_offsets, skel.channels, data)
    if scale is not None:
        if not (np.isfinite(scale) and scale > 0):
            raise LoosefitInputError(path, "scale", "a positive factor", repr(scale))
        units_scale = float(scale)
    else:
        units_scale = _units_scale(path, raw_offsets, skel.end_offsets, skel.parents, units)
    if position_channels not in ("add", "replace"):
        raise LoosefitInputError(
            path, "position_channels", "'add' or 'replace'", repr(position_channels)
        )

    # 5. Channels to local rotations and translations.
    T = frames
    rotations = np.broadcast_to(np.eye(3), (T, J, 3, 3)).copy()  # (T, J, 3, 3)
    translations = np.broadcast_to(file_offsets, (T, J, 3)).copy()  # (T, J, 3)
    by_order: dict[str, list[tuple[int, list[int]]]] = {}  # order -> [(joint, columns)]
    col = 0
    for j, chans in enumerate(skel.channels):
        cols = list(range(col, col + len(chans)))
        col += len(chans)
        rot_cols = [c for c, name in zip(cols, chans, strict=True) if name.endswith("rotation")]
        if rot_cols:
            order = "".join(name[0] for name in chans if name.endswith("rotation"))
            by_order.setdefault(order, []).append((j, rot_cols))
        for c, name in zip(cols, chans, strict=True):
            if name.endswith("position"):
                axis = "XYZ".index(name[0])
                if position_channels == "add":
                    translations[:, j, axis] += data[:, c]
                else:
                    translations[:, j, axis] = data[:, c]
    for order, members in by_order.items():  # one call per rotation order, all its joints
        joints = [j for j, _ in members]
        angles = data[:, [cols for _, cols in members]]  # (T, Jo, len(order))
        rotations[:, joints] = euler_to_matrix(angles, order, dtype=np.float64)

    return BvhClip(
        path=path,
        joint_names=tuple(skel.names),
        parents=parents,
        offsets=(raw_offsets * units_scale).astype(np.float32),
        channels=list(skel.channels),
        end_offsets={
            j: (np.asarray(o) * units_scale).astype(np.float32) for j, o in skel.end_offsets.items()
        },
        rotations=rotations.astype(np.float32),
        local_translations=(translations * units_scale).astype(np.float32),
        frame_time=frame_time,
        units_scale=units_scale,
        meta={"bones_from_frames": [skel.names[j] for j in from_frames]} if from_frames else {},
    )
