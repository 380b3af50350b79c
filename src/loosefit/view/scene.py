"""What the viewer shows: garment sequences of one motion, each with its posed body.

:func:`load_sequences` reads sequence files (:class:`~loosefit.sequence.GarmentSequence`
or a data set's clips), :func:`from_animated` takes them from memory, and
:func:`check_together` refuses sequences that cannot share one timeline and one
colouring: another number of frames, another frame rate or another garment (the error
names both). The body is posed once per avatar and motion (the simulation and a model's
rollout of the same clip share theirs), in chunks, with a progress callback.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.garment.fingerprint import same_garment
from loosefit.sequence import GarmentSequence
from loosefit.types import GarmentTemplate

POSE_CHUNK = 128  # frames posed at a time: the progress bar's step, and bounded memory


@dataclass
class ViewSequence:
    """One garment sequence on its body, as the viewer plays it.

    Attributes:
        name: its label in the panel.
        source: where it came from (a file, ``DATASET:CLIP``), for messages.
        garment: (T, V, 3) float32 garment vertices, world frame, metres.
        template: the garment at rest (faces, rest lengths for the strain).
        body: (T, Vb, 3) float32 the posed body (shared with the other sequences of the
            same avatar and motion).
        body_faces: (Fb, 3) int64 the body's triangles.
        fps: frames per second.
    """

    name: str
    source: str
    garment: np.ndarray
    template: GarmentTemplate
    body: np.ndarray
    body_faces: np.ndarray
    fps: float

    @property
    def num_frames(self) -> int:
        return int(self.garment.shape[0])


def check_together(sequences: Sequence[GarmentSequence], sources: Sequence[str]) -> None:
    """Refuse sequences that cannot play on one timeline with one colouring.

    Raises:
        LoosefitInputError: naming both sources, when two have other frame counts, frame
            rates or garments (triangles and rest shape, :func:`same_garment`).
    """
    first, src0 = sequences[0], sources[0]
    hint = "open sequences of the same garment and motion together, the others one at a time"
    for seq, src in zip(sequences[1:], sources[1:], strict=True):
        where = f"{src0} and {src}"
        if seq.num_frames != first.num_frames:
            raise LoosefitInputError(
                where,
                "garment_vertices",
                f"{first.num_frames} frames (as {src0})",
                f"{seq.num_frames} frames in {src}",
                hint=hint,
            )
        if abs(seq.fps - first.fps) > 1e-6:
            raise LoosefitInputError(
                where, "fps", f"{first.fps:g} (as {src0})", f"{seq.fps:g} in {src}", hint=hint
            )
        if not same_garment(seq.garment, first.garment):
            raise LoosefitInputError(
                where,
                "vertices, faces",
                f"the garment of {src0} ('{first.garment.name}', "
                f"{first.garment.num_vertices} vertices)",
                f"another garment in {src} "
                f"('{seq.garment.name}', {seq.garment.num_vertices} vertices)",
                hint=hint,
            )


def pose_bodies(
    sequences: Sequence[GarmentSequence], progress: Callable[[int, int], None] | None = None
) -> list[tuple[np.ndarray, np.ndarray]]:
    """The posed body of each sequence, ``(vertices (T, Vb, 3) float32, faces (Fb, 3))``,
    posed once per distinct avatar and motion.

    Args:
        sequences: the sequences.
        progress: called as ``progress(frames posed, frames to pose)``.
    """
    from loosefit.body.avatar import Avatar

    keys = [_body_key(s) for s in sequences]
    distinct = list(dict.fromkeys(keys))
    todo = [sequences[keys.index(k)] for k in distinct]
    total, done = sum(s.num_frames for s in todo), 0
    avatars: dict[str, Avatar] = {}
    posed = {}
    for key, seq in zip(distinct, todo, strict=True):
        config = seq.avatar_config()
        akey = repr((config.rig, sorted(config.shape.items())))
        if akey not in avatars:
            avatars[akey] = Avatar(config)
        avatar = avatars[akey]
        T = seq.num_frames
        body = None
        for start in range(0, T, POSE_CHUNK):
            chunk = avatar.pose_motion(seq.motion.slice(start, min(start + POSE_CHUNK, T)))
            verts = chunk.vertices.cpu().numpy()  # (t, Vb, 3)
            if body is None:
                body = np.empty((T, verts.shape[1], 3), np.float32)
            body[start : start + len(verts)] = verts
            done += len(verts)
            if progress is not None:
                progress(done, total)
        posed[key] = (body, avatar.faces.cpu().numpy().astype(np.int64))
    return [posed[k] for k in keys]


def _body_key(seq: GarmentSequence) -> tuple:
    """What the posed body depends on: the avatar and the motion's arrays."""
    m = seq.motion
    return (
        repr(sorted(seq.avatar.items(), key=lambda kv: kv[0])),
        m.joint_names,
        m.rotations.tobytes(),
        m.root_translation.tobytes(),
    )


def from_animated(
    sequences: Sequence[GarmentSequence],
    names: Sequence[str] | None = None,
    sources: Sequence[str] | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> list[ViewSequence]:
    """Sequences in memory as the viewer's, checked to play together, bodies posed.

    Args:
        sequences: one or more animated garments of the same garment and frames.
        names: their labels (default: ``source`` of each, made unique).
        sources: where each came from, for errors (default: ``sequence 1``, ...).
        progress: the bodies' posing, ``progress(done, total)``.
    """
    if not sequences:
        raise LoosefitInputError("view", "sequences", "one or more sequences", "none")
    sources = list(sources or [f"sequence {i + 1}" for i in range(len(sequences))])
    check_together(sequences, sources)
    names = list(names or _unique([s.source for s in sequences]))
    bodies = pose_bodies(sequences, progress)
    return [
        ViewSequence(name, src, s.garment_vertices, s.garment, body, faces, s.fps)
        for s, name, src, (body, faces) in zip(sequences, names, sources, bodies, strict=True)
    ]


class ReadSequences(NamedTuple):
    """The sequences :func:`read_sequences` read, in the order shown."""

    sequences: list[GarmentSequence]  # each as read and validated
    labels: list[str]  # each one's label: its file stem (made unique), or the clip's
    sources: list[str]  # where each came from: a file, or DATA:CLIP


def read_sequences(
    paths: Sequence[str | Path] = (),
    data: str | Path | None = None,
    clip: str | None = None,
) -> ReadSequences:
    """Sequence files, and a data set's clip, read and validated.

    Args:
        paths: sequence ``.npz`` files (any :mod:`loosefit.sequence` file, or a data set's
            ``sequences/NAME.npz``, read through its data set).
        data: a data set folder, with ``clip``: its simulated clip, shown first.
        clip: the clip's name in ``data``.

    Returns:
        :class:`ReadSequences`: the sequences, their labels (file stems, made unique) and
        sources.
    """
    from loosefit.data.format import DatasetReader

    seqs, labels, sources = [], [], []
    if (data is None) != (clip is None):
        raise LoosefitInputError(
            "--data/--clip",
            "clip",
            "both --data DATASET and --clip NAME, or neither",
            f"data={data!r}, clip={clip!r}",
        )
    if data is not None:
        reader = DatasetReader(data, allow_incomplete=True)
        seqs.append(reader.read(clip))
        labels.append(f"{clip} (simulation)")
        sources.append(f"{data}:{clip}")
    for p in paths:
        p = Path(p)
        seqs.append(_read_file(p))
        labels.append(p.stem)
        sources.append(str(p))
    if not seqs:
        raise LoosefitInputError(
            "view", "SEQUENCE", "a sequence .npz or --data and --clip", "nothing to view"
        )
    return ReadSequences(seqs, _unique(labels), sources)


def _read_file(path: Path) -> GarmentSequence:
    from loosefit.data.format import DatasetReader

    root = path.parent.parent
    if path.parent.name == "sequences" and (root / "manifest.json").is_file():
        return DatasetReader(root, allow_incomplete=True).read(path.stem)
    return GarmentSequence.load(path)


def _unique(labels: Sequence[str]) -> list[str]:
    """The labels, a repeated one numbered (``a``, ``a (2)``)."""
    seen: dict[str, int] = {}
    out = []
    for label in labels:
        seen[label] = seen.get(label, 0) + 1
        out.append(label if seen[label] == 1 else f"{label} ({seen[label]})")
    return out
