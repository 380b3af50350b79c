"""Scoring through the API: a trained model rolled out on held-out clips and scored against
the simulation, and against each clip's members simulated from other seeds, with its report
(:mod:`loosefit.eval.rollouts`, :mod:`loosefit.eval.ensemble`, :mod:`loosefit.eval.report`);
and a clip's cloth that goes deeper into the body than the tolerance, where and why, with
renders of the worst frames (:mod:`loosefit.eval.penetration`). Each imports what it needs
when called.

::

    import loosefit
    from loosefit.api.evaluate import diagnose_clip, evaluate, open_clip

    figures = evaluate(loosefit.load("run/model.pt"), "datasets/dance", out="out/evaluate")
    found = diagnose_clip(open_clip("datasets/dance", "05_02"))
    print(found.summary(), found.table(), sep="\\n")
    found.write_report("out/diagnose", found.render_worst("out/diagnose"))
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from loosefit.errors import LoosefitInputError

if TYPE_CHECKING:
    import numpy as np

    from loosefit.body.regions import BodyParts
    from loosefit.eval.penetration import Diagnosis
    from loosefit.sequence import GarmentSequence

Progress = Callable[[int, int], None]  # progress(done, total)
Log = Callable[[str], None]  # a line of progress for a person


# -- a model scored against the simulation ----------------------------------------------------


class Evaluation:
    """A trained model and the ground truth it is scored against, read and checked before
    any rollout (:func:`open_evaluation`): :meth:`rollouts`, then :meth:`ensemble` where
    clips have members, then :meth:`write_report`.

    Attributes:
        model: the trained stages (an :class:`~loosefit.api.Animator`'s ``model``).
        checkpoint: the file the model was read from.
        name: the model's name in the report (its checkpoint's folder).
        split: the data set's clips scored.
        data: the data set's reader, or the sequences by name.
        where: the data set's folder, or the sequence files (resolved), as the report
            records them.
        sources: the data set and the members' data sets (the corpus first); empty for
            sequence files.
        members: each clip's members, gathered and checked
            (:func:`~loosefit.eval.ensemble_members.gather_ensembles`); None where no clip
            has any.
    """

    def __init__(self, model, data, where, *, split: str, sources: list, members) -> None:
        self.model = getattr(model, "model", model)
        self.checkpoint = Path(model.path)
        self.name = self.checkpoint.parent.name
        self.split, self.data, self.where = split, data, where
        self.sources, self.members = sources, members

    @property
    def title(self) -> str:
        """The report's title."""
        return f"Rollouts of {self.name}"

    def rollouts(
        self,
        *,
        horizons: tuple[int, ...] | None = None,
        surface: bool = True,
        max_frames: int | None = None,
        stages=None,
        threads: int | None = None,
    ) -> dict:
        """Every clip rolled out from its first frame and scored against the simulation
        (:func:`~loosefit.eval.rollouts.evaluate_rollouts`).

        Args:
            horizons: frames for the iter-N errors (None: 100, 500 and 1200, the paper's).
            surface: Hausdorff and STED too (slower).
            max_frames: roll out at most this many frames a clip.
            stages: the stages after the decoders
                (:class:`~loosefit.inference.stages.Stages`; None: all).
            threads: torch's intra-op threads meanwhile (None: the free cores, at most 4).

        Returns:
            Per clip and overall: frames, RMSE (cm) over the clip and per horizon, the RMSE
            of every frame, Hausdorff, STED, frames per second; then ``checkpoint`` and
            ``dataset``.
        """
        from loosefit.eval.rollouts import HORIZONS, evaluate_rollouts
        from loosefit.inference.threads import inference_threads

        with inference_threads(threads):
            result = evaluate_rollouts(
                self.model,
                self.data,
                self.split,
                horizons=HORIZONS if horizons is None else tuple(horizons),
                surface=surface,
                max_frames=max_frames,
                stages=stages,
            )
        result["checkpoint"] = str(self.checkpoint.resolve())
        result["dataset"] = self.where
        return result

    def ensemble(
        self,
        *,
        surface: bool = True,
        stages=None,
        threads: int | None = None,
        progress: Log | None = None,
        realisations: int = 0,
    ) -> dict:
        """The model rolled out on every clip with members and scored against them: the
        simulation's own spread, RMSE to their mean, the energy score, hem flare and speed
        against their range, the raised knee
        (:func:`~loosefit.eval.ensemble.evaluate_ensemble`).

        Args:
            surface: Hausdorff and STED too.
            stages: the stages after the decoders (None: all).
            threads: torch's intra-op threads meanwhile (None: the free cores, at most 4).
            progress: called with a line a step.
            realisations: S > 0: a model with a residual process is scored by its
                realisations 0..S-1 (the energy score with its spread); 0: its one garment.

        Raises:
            LoosefitInputError: no clip with members (:attr:`members` None) or none with
                two or more, or ``realisations`` not an int >= 0.
        """
        from loosefit.eval.ensemble import evaluate_ensemble
        from loosefit.inference.threads import inference_threads

        if self.members is None:
            raise LoosefitInputError(
                self.where, "members", "clips simulated from several seeds", "none"
            )
        if not (isinstance(realisations, int) and realisations >= 0):
            raise LoosefitInputError("evaluate", "realisations", "an integer >= 0", realisations)
        with inference_threads(threads):
            return evaluate_ensemble(
                {self.name: self.model},
                self.sources,
                self.split,
                surface=surface,
                stages=stages,
                progress=progress,
                ensembles=self.members,
                realisations=realisations,
            )

    def write_report(self, result: dict, out: str | Path) -> Path:
        """``evaluation.md``, ``.csv``, ``.json`` and ``rmse_per_frame.png`` of ``result``
        (:meth:`rollouts`, with :meth:`ensemble`'s as its ``"ensemble"``) in the folder
        ``out``, the JSON last (:func:`~loosefit.eval.report.write_rollout_report`).

        Returns:
            The Markdown page's path.
        """
        from loosefit.eval.report import write_rollout_report

        return write_rollout_report(result, out, self.title) / "evaluation.md"


def open_evaluation(
    model, data: str | Path | Sequence[str | Path], *, split: str = "test", members=()
) -> Evaluation:
    """A model and its ground truth, read and checked before any rollout.

    Args:
        model: an :class:`~loosefit.api.Animator` (:func:`loosefit.load`).
        data: a data set folder (its ``split`` scored), or sequence files (each the ground
            truth of its motion, e.g. from :func:`loosefit.simulate`).
        split: with a data set: ``"train"``, ``"test"`` or ``"all"``.
        members: data sets of the same clips simulated from other seeds (``loosefit
            simulate --seeds``); members inside ``data`` (``NAME@seedS``) count without
            them.

    Raises:
        LoosefitInputError: members without a data set, an unreadable data set or
            sequence, or members that differ in anything but the seed.
    """
    from loosefit.data.format import DatasetReader, read_any_sequence
    from loosefit.eval.ensemble_members import gather_ensembles

    files = [data] if isinstance(data, str | Path) else list(data)
    if len(files) == 1 and Path(files[0]).is_dir():
        reader = DatasetReader(files[0])
        where = str(Path(files[0]).resolve())
    else:  # sequences: the ground truth of each motion
        reader = {Path(f).stem: read_any_sequence(f) for f in files}
        where = [str(Path(f).resolve()) for f in files]
    if members and not isinstance(reader, DatasetReader):
        raise LoosefitInputError(
            "--members", "--data", "a data set folder to gather members with", "sequence files"
        )
    sources, gathered = [], None  # each clip's members, checked before any rollout
    if isinstance(reader, DatasetReader):
        sources = [files[0], *members]
        if members or has_members(reader, split):
            gathered = gather_ensembles(sources, split)
    return Evaluation(model, reader, where, split=split, sources=sources, members=gathered)


def has_members(reader, split: str) -> bool:
    """Whether a data set (a :class:`~loosefit.data.format.DatasetReader`) holds a clip of
    ``split`` simulated from more than one seed."""
    from loosefit.eval.ensemble_members import member_clip

    names = reader.split(split)
    return any(member_clip(n)[1] is not None for n in names)


def evaluate(
    model,
    data: str | Path | Sequence[str | Path],
    *,
    split: str = "test",
    members=(),
    horizons: tuple[int, ...] | None = None,
    surface: bool = True,
    max_frames: int | None = None,
    stages=None,
    threads: int | None = None,
    out: str | Path | None = None,
    progress: Log | None = None,
    realisations: int = 0,
) -> dict:
    """A trained model rolled out on a data set's held-out clips (or sequences) and scored
    against the simulation, and against each clip's members where it has any; its report
    written to ``out``. :func:`open_evaluation`, then :meth:`Evaluation.rollouts`,
    :meth:`Evaluation.ensemble` and :meth:`Evaluation.write_report`: see them for the
    arguments.

    Returns:
        The figures, as ``evaluation.json`` holds them (the ensemble's as ``"ensemble"``).
    """
    evaluation = open_evaluation(model, data, split=split, members=members)
    result = evaluation.rollouts(
        horizons=horizons, surface=surface, max_frames=max_frames, stages=stages, threads=threads
    )
    if evaluation.members is not None:
        result["ensemble"] = evaluation.ensemble(
            surface=surface,
            stages=stages,
            threads=threads,
            progress=progress,
            realisations=realisations,
        )
    if out is not None:
        evaluation.write_report(result, out)
    return result


# -- a clip's penetrations diagnosed ----------------------------------------------------------

ARMS = {"none": False, "upper": "upper", "all": True}  # the collider's arms by name; or "auto"


@dataclass
class Clip:
    """A clip to diagnose (:func:`open_clip`).

    Attributes:
        sequence: the simulated clip (:class:`~loosefit.sequence.GarmentSequence`).
        name: its name (the data set's, or the file's stem).
        source: the data set folder or the sequence file it was read from.
        arms: the collider's arms: False, "upper" or True.
    """

    sequence: GarmentSequence
    name: str
    source: Path
    arms: bool | str

    @property
    def shape(self) -> dict:
        """The body's shape it was simulated on, as anny phenotypes."""
        return dict(self.sequence.avatar.get("shape", {}))


def open_clip(source: str | Path, clip: str | None = None, *, arms: str = "auto") -> Clip:
    """A data set's clip, or a sequence file, and the arms its collider has.

    Args:
        source: a data set folder (then ``clip``), or a sequence ``.npz``.
        clip: with a data set: the clip's name.
        arms: ``"auto"`` (the data set's cloth configuration, else the garment's
            :func:`~loosefit.fitting.place.collider_arms`), ``"none"``, ``"upper"`` or
            ``"all"``.

    Raises:
        LoosefitInputError: a data set without ``clip``, a sequence file with one, an
            unreadable clip, or an unknown ``arms``.
    """
    import json

    from loosefit.data.format import DatasetReader, read_any_sequence
    from loosefit.fitting.place import collider_arms
    from loosefit.inference.model_common import arm_collision_of

    if arms != "auto" and arms not in ARMS:
        raise LoosefitInputError("diagnose", "arms", "auto, none, upper or all", repr(arms))
    source = Path(source)
    if source.is_dir():
        if not clip:
            raise LoosefitInputError(
                source,
                "CLIP",
                "a clip of the data set after it",
                "none",
                hint="its clips: sequences/*.npz",
            )
        seq, name = DatasetReader(source, allow_incomplete=True).read(clip), clip
        manifest = source / "manifest.json"
    else:
        if clip:
            raise LoosefitInputError(source, "CLIP", "no clip after a sequence file", clip)
        seq, name = read_any_sequence(source), source.stem
        manifest = source.parent.parent / "manifest.json"  # a data set's sequences/NAME.npz
    collider = ARMS.get(arms)
    if arms == "auto":
        config = json.loads(manifest.read_text()).get("config", {}) if manifest.is_file() else {}
        collider = arm_collision_of(config, collider_arms(seq.garment))
    return Clip(seq, name, source, collider)


@dataclass
class ClipDiagnosis:
    """Where and why a clip's cloth goes deeper into the body than the tolerance
    (:func:`diagnose_clip`).

    Attributes:
        clip: the clip diagnosed.
        diagnosis: its penetrations, motion signals and events
            (:class:`~loosefit.eval.penetration.Diagnosis`).
        body: (T, Vb, 3) the posed body.
        body_faces: (F, 3) its triangles.
        parts: the body's parts and the collider
            (:class:`~loosefit.body.regions.BodyParts`).
        tolerance: m of depth that count.
    """

    clip: Clip
    diagnosis: Diagnosis
    body: np.ndarray
    body_faces: np.ndarray
    parts: BodyParts
    tolerance: float

    def summary(self) -> str:
        """One line: the clip, its figures, the collider's arms."""
        return f"{self.clip.name}: {self.diagnosis.summary()}; arms collide: {self.clip.arms}"

    def table(self) -> str:
        """The events, a line each, and their causes
        (:func:`~loosefit.eval.penetration.format_events`)."""
        from loosefit.eval.penetration import format_events

        return format_events(self.diagnosis.events, self.tolerance)

    def render_worst(
        self,
        out: str | Path,
        *,
        top: int = 3,
        size: int = 360,
        written: Callable[[Path], None] | None = None,
    ) -> list[Path]:
        """PNGs of the ``top`` worst frames, each whole and close up on its deepest cloth,
        the collider's parts muted, in the folder ``out`` (``worstR_frameT.png``;
        :func:`~loosefit.render.closeup.render_penetration`).

        Args:
            out: the folder.
            top: how many frames (those with deep cloth, deepest first).
            size: pixels a view.
            written: called with each file's path once written.

        Returns:
            The PNGs' paths, worst first.
        """
        if top < 0:
            raise LoosefitInputError("diagnose", "top", "top >= 0", top)
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        frames = self.diagnosis.worst_frames(top)
        return _render_frames(self, frames, out, size, written) if frames else []

    def to_json(self, renders: list[Path] = ()) -> dict:
        """What ``diagnosis.json`` holds: the clip, its source and collider, the
        diagnosis's figures and events, and the renders' paths."""
        return {
            "clip": self.clip.name,
            "source": str(self.clip.source),
            "arm_collision": self.clip.arms,
            **self.diagnosis.to_json(),
            "renders": [str(p) for p in renders],
        }

    def write_report(self, out: str | Path, renders: list[Path] = ()) -> Path:
        """``diagnosis.json`` (:meth:`to_json`) in the folder ``out``; its path."""
        from loosefit.data.format import write_json_atomic

        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        write_json_atomic(out / "diagnosis.json", self.to_json(renders))
        return out / "diagnosis.json"


def diagnose_clip(
    clip: Clip,
    *,
    avatar=None,
    device: str = "cpu",
    tolerance: float | None = None,
    merge_gap: int = 0,
    progress: Progress | None = None,
) -> ClipDiagnosis:
    """Where and why ``clip``'s cloth goes deeper into the body than ``tolerance``: its
    penetrations by body part, the motion's signals, and events of frames in a row with
    their likely causes (:func:`~loosefit.eval.penetration.diagnose_clip`).

    Args:
        clip: :func:`open_clip`'s.
        avatar: the body it was simulated on (an :class:`~loosefit.body.avatar.Avatar`;
            None: anny of the clip's shape, built on ``device``).
        device: torch device to pose the body on, where ``avatar`` is None.
        tolerance: m of depth that count (None: simulate's, 5 mm).
        merge_gap: frames without penetration that still join two events.
        progress: called as ``progress(done, total)``.

    Raises:
        LoosefitInputError: a tolerance outside (0, 1) m, a negative merge gap, or a
            motion the avatar cannot pose.
    """
    import torch

    from loosefit.api import penetration_tolerance
    from loosefit.body.regions import body_parts
    from loosefit.eval.penetration import diagnose_clip as diagnose

    tolerance = penetration_tolerance() if tolerance is None else tolerance
    if not 0.0 < tolerance < 1.0 or merge_gap < 0:
        raise LoosefitInputError(
            "diagnose",
            "tolerance, merge_gap",
            "0 < tolerance < 1 m, merge gap >= 0",
            f"{tolerance}, {merge_gap}",
        )
    if avatar is None:
        from loosefit.body.avatar import Avatar, AvatarConfig

        avatar = Avatar(AvatarConfig(shape=clip.shape), device=device)
    seq = clip.sequence
    avatar.check_motion(seq.motion)
    with torch.no_grad():
        body = avatar.pose_motion(seq.motion).vertices.float().cpu().numpy()  # (T, Vb, 3)
    parts = body_parts(avatar, clip.arms)
    found = diagnose(
        seq.garment_vertices,
        body,
        seq.motion.rotations[:, 0],
        seq.fps,
        parts,
        tolerance=tolerance,
        merge_gap=merge_gap,
        progress=progress,
    )
    faces = avatar.faces.cpu().numpy()
    return ClipDiagnosis(clip, found, body, faces, parts, tolerance)


def _render_frames(
    found: ClipDiagnosis,
    frames: list[int],
    out: Path,
    size: int,
    written: Callable[[Path], None] | None,
) -> list[Path]:
    """:meth:`ClipDiagnosis.render_worst`'s PNGs of ``frames``."""
    from PIL import Image

    from loosefit.eval.penetration import closeup
    from loosefit.render.closeup import render_penetration
    from loosefit.render.renderer import RenderConfig, Renderer

    seq, name, parts = found.clip.sequence, found.clip.name, found.parts
    pen, paths = found.diagnosis.penetrations, []
    config = RenderConfig(width=size, height=size, labels=False, frame_counter=False)
    with Renderer(config) as renderer:
        for rank, t in enumerate(frames, 1):
            root = seq.motion.root_translation[t]
            view = closeup(pen, parts, t, seq.garment.num_vertices, root)
            title = (
                f"{name} frame {t} ({t / seq.fps:.2f} s): {int(view.deep.sum())} vertices "
                f"deeper than {1000 * pen.tolerance:.0f} mm, deepest "
                f"{100 * pen.max_depth[t]:.1f} cm, in the {view.regions[0]}"
            )
            image = render_penetration(
                found.body[t],
                found.body_faces,
                seq.garment_vertices[t],
                seq.garment.faces,
                view.deep,
                view.target,
                direction=view.direction,
                hidden=view.hidden,
                muted=~parts.colliding,
                size=size,
                title=title,
                hidden_label=", ".join(view.regions),
                renderer=renderer,
            )
            paths.append(out / f"worst{rank}_frame{t:05d}.png")
            Image.fromarray(image).save(paths[-1], optimize=True)
            if written is not None:
                written(paths[-1])
    return paths
