"""An ensemble's members: the same clip simulated from different seeds, gathered from one
or several data sets (:func:`gather_ensembles`) and checked to share the garment, avatar,
cloth configuration and motion (:func:`check_members`); what
:mod:`loosefit.eval.ensemble` scores a prediction against.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from loosefit.errors import LoosefitInputError

# A member's motion may differ from another's this much in a rotation matrix entry: the
# pose correction turns an arm a little differently on a shorter clip (up to about 0.02).
ROTATION_TOLERANCE = 0.05
TRANSLATION_TOLERANCE = 1.0e-3  # m, the root's position
# configuration fields members must share (the seed and the device aside)
SHARED_CONFIG = ("garment", "cloth", "unfold", "fps", "shape")
MEMBER_FREE = ("seed", "device")  # cloth fields that may differ between members


def member_clip(name: str) -> tuple[str, int | None]:
    """A sequence's clip and member seed: ``"05_10@seed2"`` -> ``("05_10", 2)``; a plain name
    is its clip's member of the data set's own seed (``None``).
    (:func:`loosefit.sim.jobs.split_member`, the naming ``loosefit simulate --seeds`` uses.)"""
    from loosefit.sim.jobs import split_member

    return split_member(name)


def clip_key(name: str) -> str:
    """The key members of one clip share across data sets: the clip's name without a member
    suffix, a held-out chain's ``chain_`` prefix left out (a data set of a chain's first
    frames names it by its parts)."""
    return member_clip(name)[0].removeprefix("chain_")


@dataclass
class Member:
    """One simulation of a clip.

    Attributes:
        name: the sequence's name in its data set.
        source: the data set's folder.
        seed: the member's seed (the manifest's ``member_seed``, else the data set's seed).
        flagged: the simulator's quality gate's reason where it flagged the clip, else "".
    """

    name: str
    source: Path
    seed: int
    flagged: str = ""
    reader: object = field(default=None, repr=False)

    @property
    def label(self) -> str:
        return f"seed {self.seed}"

    def read(self):
        return self.reader.read(self.name)


@dataclass
class Ensemble:
    """A clip's members, checked to share the garment, avatar, configuration and motion.

    Attributes:
        clip: the clip's name (the first data set's).
        members: at least one :class:`Member`.
        frames: the frames every member has (members of different lengths are scored on
            the frames they share).
        motion_difference: the largest difference of the members' joint rotations.
    """

    clip: str
    members: list[Member]
    frames: int
    motion_difference: float = 0.0

    sequences: list = field(default_factory=list, repr=False)  # each member's, as read

    def vertices(self) -> np.ndarray:
        """(M, T, V, 3) float32 the members' garments on the shared frames."""
        return np.stack([s.garment_vertices[: self.frames] for s in self.sequences])


def _diff(a, b, path: str = "") -> list[tuple[str, object, object]]:
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            out += _diff(a.get(k), b.get(k), f"{path}.{k}" if path else k)
        return out
    return [] if a == b else [(path, a, b)]


def check_members(
    clip: str, members: list[Member], configs: list[dict], avatars: list[dict], sequences: list
) -> tuple[int, float]:
    """Refuse members that differ in anything but the seed.

    Args:
        clip: the clip's name, for messages.
        members: the members; configs: each one's data set configuration (the manifest's,
            completed); avatars: each one's body; sequences: each one's sequence.

    Returns:
        The frames all members share and the largest joint-rotation difference over them.

    Raises:
        LoosefitInputError: naming the member, the field and both values.
    """
    first, cfg0 = members[0], configs[0]
    seq0 = sequences[0]
    from loosefit.garment.fingerprint import same_garment

    frames = min(s.motion.num_frames for s in sequences)
    worst = 0.0
    for m, cfg, body, seq in zip(members[1:], configs[1:], avatars[1:], sequences[1:], strict=True):
        where = f"{m.source}:{m.name}"
        theirs = f"{first.source}:{first.name}"
        if not same_garment(seq0.template, seq.template):
            raise LoosefitInputError(
                where, "template.npz", f"the garment of {theirs}", "another garment"
            )
        if body != avatars[0]:
            raise LoosefitInputError(where, "body", f"{avatars[0]} (as {theirs})", f"{body}")
        for key in SHARED_CONFIG:
            a, b = cfg0.get(key), cfg.get(key)
            if key == "cloth":
                a = {k: v for k, v in (a or {}).items() if k not in MEMBER_FREE}
                b = {k: v for k, v in (b or {}).items() if k not in MEMBER_FREE}
            for path, x, y in _diff(a, b, key):
                raise LoosefitInputError(
                    where,
                    f"config.{path}",
                    f"{x!r} (as {theirs}: members differ in the seed alone)",
                    f"{y!r}",
                )
        ma, mb = seq0.motion, seq.motion
        if tuple(ma.joint_names) != tuple(mb.joint_names):
            raise LoosefitInputError(
                where, "motion.joint_names", f"those of {theirs}", "other joints"
            )
        if abs(ma.fps - mb.fps) > 1e-6:
            raise LoosefitInputError(where, "motion.fps", f"{ma.fps} (as {theirs})", f"{mb.fps}")
        rot = float(np.abs(ma.rotations[:frames] - mb.rotations[:frames]).max())
        if rot > ROTATION_TOLERANCE:
            raise LoosefitInputError(
                where,
                "motion.rotations",
                f"the motion of {theirs} (within {ROTATION_TOLERANCE} in a rotation entry)",
                f"a difference of {rot:.3f}",
            )
        move = float(np.abs(ma.root_translation[:frames] - mb.root_translation[:frames]).max())
        if move > TRANSLATION_TOLERANCE:
            raise LoosefitInputError(
                where,
                "motion.root_translation",
                f"the motion of {theirs} (within {TRANSLATION_TOLERANCE * 1000:.0f} mm)",
                f"a difference of {move * 1000:.1f} mm",
            )
        worst = max(worst, rot)
    return frames, worst


def gather_ensembles(
    sources: list[str | Path], split: str = "test", flagged: bool = True
) -> dict[str, Ensemble]:
    """The members of each clip across data sets of the same clips.

    A clip's members are its sequences in every data set given: its own name, the name with
    a member suffix (``NAME@seedS``, :func:`member_clip`), or a chain's name without its
    ``chain_`` prefix (:func:`clip_key`). The first data set's ``split`` decides the clips;
    in the others every sequence counts (a member simulated for the ensemble alone).

    Args:
        sources: data set folders (the corpus first).
        split: the first data set's clips: "train", "test" or "all".
        flagged: count members the simulator's quality gate flagged (they are noted).

    Returns:
        Per clip (the first data set's name), its :class:`Ensemble`, checked by
        :func:`check_members`.
    """
    from loosefit.data.format import DatasetReader
    from loosefit.sim.manifest import stored_config

    if not sources:
        raise LoosefitInputError("ensemble", "data", "at least one data set", "none")
    readers = [DatasetReader(s, allow_incomplete=True) for s in sources]
    wanted = readers[0].split(split)
    names: dict[str, str] = {}
    for n in wanted:
        names.setdefault(clip_key(n), member_clip(n)[0])
    found: dict[str, list[tuple[Member, dict, dict]]] = {k: [] for k in names}
    for i, reader in enumerate(readers):
        cfg = stored_config(reader.manifest)
        entries = reader.manifest.get("sequences", {})
        # the first data set's split; every sequence of the others (a flagged member too)
        pool = wanted if i == 0 else list(dict.fromkeys([*entries, *reader.split("all")]))
        for n in pool:
            key = clip_key(n)
            entry = entries.get(n, {})
            if key not in found or not reader.sequence_path(n).is_file():
                continue
            reason = entry.get("reason", "") if entry.get("status") == "flagged" else ""
            if reason and not flagged:
                continue
            seed = entry.get("member_seed", member_clip(n)[1])
            seed = int(cfg.get("seed", 0) if seed is None else seed)
            found[key].append((Member(n, reader.root, seed, reason, reader), cfg, reader.avatar))
    out = {}
    for key, got in found.items():
        if not got:
            continue
        members = [g[0] for g in got]
        seeds = [m.seed for m in members]
        if len(set(seeds)) != len(seeds):
            dup = next(s for s in seeds if seeds.count(s) > 1)
            which = [f"{m.source}:{m.name}" for m in members if m.seed == dup]
            raise LoosefitInputError(
                names[key], "members", "one member per seed", f"seed {dup} in {which}"
            )
        seqs = [m.read() for m in members]
        frames, diff = check_members(
            names[key], members, [g[1] for g in got], [g[2] for g in got], seqs
        )
        out[names[key]] = Ensemble(names[key], members, frames, diff, seqs)
    return out
