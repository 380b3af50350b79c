"""A data set's clips: the jobs a configuration makes, their names, and their motions.

An ensemble (``DatasetConfig.seeds``) simulates each clip once per seed: its members. A
member's motion is its clip's; its cloth's start is jittered from its own seed. The member
of the data set's ``seed`` keeps the clip's name, every other is ``NAME@seedS``
(:func:`member_name`, :func:`split_member`).
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.sim.dataset_config import DatasetConfig, MotionSource, check_seeds

if TYPE_CHECKING:
    from loosefit.body.regions import BodyParts
    from loosefit.types import Motion


@dataclass
class Job:
    """One clip to simulate."""

    name: str  # the clip's name: its sequence file's and its manifest entry's
    spec: str  # a load_motion spec: a .bvh path, a move name or dance:SECONDS
    seed: int  # seeds its motion (a dance) and, unless jitter_seed is given, its cloth's jitter
    test: bool  # held out for testing
    jitter_seed: int | None = None  # seeds its cloth's jitter (None: seed)
    member_seed: int | None = None  # an ensemble member's seed (None: not in an ensemble)

    def __post_init__(self) -> None:
        if self.jitter_seed is None:
            self.jitter_seed = self.seed


def plan_jobs(config: DatasetConfig) -> list[Job]:
    """The clips of a dataset, in a fixed order.

    With ``config.seeds`` (an ensemble), each clip is one job per member seed ``s``, in
    that order: the clip's motion (its motion seed, ``Job.seed``, unchanged), its cloth's
    jitter seeded ``clip seed - config.seed + s`` (the clip as a data set of ``seed`` ``s``
    would simulate it), named by :func:`member_name`, held out as the clip is.

    Raises:
        LoosefitInputError: a bad motion source, ``seeds`` not distinct integers >= 0
            (refused first), or, with ``seeds``, a clip already named like a member.
    """
    seeds = check_seeds(config.seeds)
    jobs = _clips(config)
    if seeds is None:
        return jobs
    for job in jobs:
        if split_member(job.name)[1] is not None:
            raise LoosefitInputError(
                "DatasetConfig",
                "seeds",
                "clips whose names do not end in @seedN (an ensemble names its members so)",
                f"a clip named {job.name!r}",
            )
    return [
        Job(
            member_name(job.name, s, config.seed),
            job.spec,
            job.seed,
            job.test,
            jitter_seed=job.seed - config.seed + s,
            member_seed=s,
        )
        for job in jobs
        for s in seeds
    ]


def member_name(name: str, seed: int, base_seed: int) -> str:
    """An ensemble member's clip name: the clip's own ``name`` for the member of the data
    set's seed ``base_seed``, ``NAME@seedS`` for any other seed ``S``."""
    return name if seed == base_seed else f"{name}@seed{seed}"


_MEMBER = re.compile(r"(.+)@seed(0|[1-9][0-9]*)")


def split_member(name: str) -> tuple[str, int | None]:
    """A clip name's ensemble clip and member seed: ``("NAME", S)`` for ``NAME@seedS``,
    ``(name, None)`` for any other (a clip's own name: the member of the data set's seed,
    or a clip of no ensemble). The inverse of :func:`member_name`."""
    m = _MEMBER.fullmatch(name)
    return (m.group(1), int(m.group(2))) if m else (name, None)


def _clips(config: DatasetConfig) -> list[Job]:
    """The clips of a dataset, one job each, in a fixed order."""
    m = config.motions
    jobs: list[Job] = []
    folder_stems: set[str] = set()  # the clips of a bvh folder
    if m.kind == "bvh" or config.preset == "paper":
        from loosefit.motion.files import motion_files

        files = motion_files(m.folder)  # .bvh, .gltf, .glb, .npz
        jobs += [
            Job(f.stem, str(f), config.seed + i, f.stem in m.test)
            for i, f in enumerate(files)
            if not (m.chain_test and f.stem in m.test)
        ]
        folder_stems = {f.stem for f in files}
        held_out = [f for f in files if f.stem in m.test]
        if m.chain_test and held_out:
            # One long held-out sequence, so that rollouts can be judged over 1,200+ frames.
            name = "chain_" + "_".join(f.stem for f in held_out)
            jobs.append(Job(name, "+".join(str(f) for f in held_out), config.seed + 500, True))
        _check_variants(m)
        folder = [(f.stem, str(f)) for f in files]
        jobs += _every_variant(m, folder, config.seed, folder=True)
    if m.kind == "procedural" and m.moves:
        for i, move in enumerate(m.moves):
            test = m.test_every > 0 and (i % m.test_every == m.test_every - 1)
            jobs.append(Job(f"{move}_{i:03d}", move, config.seed + 1000 + i, test))
    elif m.kind == "procedural" or config.preset == "paper":
        for i in range(m.count):
            seed = config.seed + 1000 + i
            test = m.test_every > 0 and (i % m.test_every == m.test_every - 1)
            jobs.append(Job(f"dance_{i:03d}", f"dance:{m.seconds}", seed, test))
    if m.kind == "specs" or (m.kind == "bvh" and m.specs):  # bvh: more clips beside the folder
        if not m.specs:
            raise LoosefitInputError("MotionSource", "specs", "at least one motion", "none")
        names = [spec_name(spec) for spec in m.specs]
        taken = [j.name for j in jobs] + names
        if len(set(taken)) != len(taken):
            dup = next(n for n in taken if taken.count(n) > 1)
            raise LoosefitInputError(
                "MotionSource", "specs", "motions with distinct names", f"two named '{dup}'"
            )
        unknown = sorted(set(m.test) - set(names) - folder_stems)
        if unknown:
            raise LoosefitInputError(
                "MotionSource",
                "test",
                f"names of the motions {sorted(set(names) | folder_stems)}",
                repr(unknown),
            )
        jobs += [
            Job(n, spec, config.seed + 2000 + i, n in m.test)
            for i, (n, spec) in enumerate(zip(names, m.specs, strict=True))
        ]
        if m.kind == "bvh":  # the named specs retimed and pitched too, after every original
            named = list(zip(names, m.specs, strict=True))
            jobs += _every_variant(m, named, config.seed, folder=False)
    if m.kind not in ("bvh", "procedural", "specs"):
        raise LoosefitInputError("MotionSource", "kind", "bvh, procedural or specs", repr(m.kind))
    known = {j.name for j in jobs} | folder_stems
    for field_name, named in _variant_clips(m):
        unknown = sorted(set(named) - known)
        if unknown:
            raise LoosefitInputError(
                "MotionSource", field_name, f"names of the motions {sorted(known)}", repr(unknown)
            )
    return jobs


def _number(value: float) -> str:
    return f"{value:g}"


def _spin_label(value: float | str) -> str:
    from loosefit.motion.spin import read_spin

    return read_spin(value).label()


def _spin_spec(value: float | str) -> str:
    from loosefit.motion.spin import read_spin

    return read_spin(value).spec()


@dataclass(frozen=True)
class _Variant:
    """One way a data set dances its clips again: the ``MotionSource`` fields of its values
    and chosen clips, the clip name's suffix and the spec's prefix (each with the value's
    text: ``name_part`` in the name, ``spec_part`` in the spec), and the seed offsets of the
    folder's clips and of the named specs'."""

    values: str
    clips: str
    suffix: str
    prefix: str
    folder_seed: int
    named_seed: int
    name_part: Callable[[float | str], str] = _number
    spec_part: Callable[[float | str], str] = _number

    def suffixed(self, value: float | str) -> str:
        """The suffix of a clip danced at ``value``."""
        return self.suffix.format(self.name_part(value))

    def prefixed(self, value: float | str) -> str:
        """The spec's prefix of a clip danced at ``value``."""
        return self.prefix.format(self.spec_part(value))


# retimed (``NAME_xSPEED``), pelvis pitched (``NAME_pitchDEG``), spun (``NAME_spinTURNS``,
# ``NAME_spinTURNS_rampS_holdS``); the seed offsets are the data sets': a change would break
# ``--reuse`` of simulated clips
_VARIANTS = (
    _Variant("speeds", "speed_clips", "_x{}", "speed:{}:", 100, 2100),
    _Variant("pitches", "pitch_clips", "_pitch{}", "pitch:{}:", 3100, 4100),
    _Variant("spins", "spin_clips", "_spin{}", "spin:{}:", 5100, 6100, _spin_label, _spin_spec),
)


def _every_variant(
    m: MotionSource, clips: list[tuple[str, str]], seed: int, *, folder: bool
) -> list[Job]:
    """The training jobs of ``clips`` ((name, spec) each) in every variant of
    :data:`_VARIANTS` (retimed, pitched, spun), in that order: the clips each variant's field
    of chosen clips names, or for a ``folder``'s clips and none chosen, every clip not held
    out. See :func:`_variants`."""
    return [
        job
        for v in _VARIANTS
        for job in _variants(
            m,
            clips,
            seed + (v.folder_seed if folder else v.named_seed),
            folder,
            values=getattr(m, v.values),
            chosen=getattr(m, v.clips),
            suffix=v.suffixed,
            prefix=v.prefixed,
        )
    ]


def _variant_clips(m: MotionSource) -> list[tuple[str, tuple[str, ...]]]:
    """Each variant's field of chosen clips and the names in it."""
    return [(v.clips, getattr(m, v.clips)) for v in _VARIANTS]


def _variants(
    m: MotionSource,
    clips: list[tuple[str, str]],
    first_seed: int,
    every: bool,
    *,
    values: tuple[float | str, ...],
    chosen: tuple[str, ...],
    suffix: Callable[[float | str], str],
    prefix: Callable[[float | str], str],
) -> list[Job]:
    """Training jobs of ``clips`` changed by each of ``values``: named ``NAME`` +
    ``suffix(value)``, their spec ``prefix(value)`` + the clip's; the
    ``chosen`` names, or with ``every`` and none chosen, every clip not held out. Value
    ``k``'s clip ``i`` is simulated from seed ``first_seed + 100 k + i``."""
    return [
        Job(name + suffix(v), prefix(v) + spec, first_seed + 100 * k + i, False)
        for k, v in enumerate(values)
        for i, (name, spec) in enumerate(clips)
        if name not in m.test and (name in chosen or (every and not chosen))
    ]


def _check_variants(m: MotionSource) -> None:
    """Refuses a speed that is not a positive factor other than 1, a pitch that is zero,
    repeated or beyond :data:`~loosefit.motion.pelvis.MAX_PITCH_DEGREES`, a spin rate that
    that does not read or is repeated (:func:`~loosefit.motion.spin.read_spin`), and a
    retimed, pitched or spun clip that is held out (a held-out motion must never be trained
    on, at any speed, pitch or spin)."""
    from loosefit.motion.pelvis import MAX_PITCH_DEGREES
    from loosefit.motion.spin import SPIN_FORM, read_spin

    for speed in m.speeds:
        if not (np.isfinite(speed) and speed > 0 and speed != 1.0):
            raise LoosefitInputError(
                "MotionSource", "speeds", "positive factors other than 1", m.speeds
            )
    for deg in m.pitches:
        if not (np.isfinite(deg) and deg != 0 and abs(deg) <= MAX_PITCH_DEGREES):
            raise LoosefitInputError(
                "MotionSource",
                "pitches",
                f"degrees other than 0, from -{MAX_PITCH_DEGREES:g} to {MAX_PITCH_DEGREES:g}",
                m.pitches,
            )
    if len({f"{d:g}" for d in m.pitches}) != len(m.pitches):
        raise LoosefitInputError("MotionSource", "pitches", "distinct degrees", m.pitches)
    spins = [read_spin(t) for t in m.spins]
    if any(spin is None for spin in spins):
        raise LoosefitInputError("MotionSource", "spins", SPIN_FORM, m.spins)
    if len({spin.label() for spin in spins}) != len(spins):
        raise LoosefitInputError("MotionSource", "spins", "distinct spins", m.spins)
    for field_name, named in _variant_clips(m):
        held = sorted(set(named) & set(m.test))
        if held:
            raise LoosefitInputError(
                "MotionSource", field_name, "clips not held out (not in test)", repr(held)
            )


def spec_name(spec: str) -> str:
    """A clip's name for a motion spec: its file stems and words, safe as a file name
    (``mirror:../a/61_01.bvh`` -> ``mirror_61_01``)."""
    parts = [
        re.sub(r"\.(bvh|npz|gltf|glb)$", "", re.sub(r"[^:+]*/", "", p)) for p in spec.split("+")
    ]
    parts = [re.sub(r"(units|scale):[^:]*:", "", p) for p in parts]  # how it is read, not what
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", "+".join(parts)).strip("._") or "motion"


def short_spec(spec: str) -> str:
    """A job's motion spec without folders: ``speed:1.25:/x/a.bvh`` -> ``speed:1.25:a.bvh``."""
    return "+".join(re.sub(r"[^:+]*/", "", part) for part in spec.split("+"))


def job_motion(
    config: DatasetConfig, job: Job, avatar, unfold: bool = True, parts: BodyParts | None = None
) -> Motion:
    """The motion a job simulates, on ``avatar``'s skeleton at the dataset's frame rate:
    with ``unfold`` (and ``config.unfold.enabled``) the poses that fold into the body
    turned out of it (:func:`~loosefit.motion.pose_correction.unfold_motion`, its queries on the
    simulation's device, ``config.cloth.device``; the correction's figures in
    ``motion.meta["unfold"]``); without, as loaded (the same frame count).

    Args:
        parts: the body parts the pose correction tests (:func:`limb_parts`); built here
            when needed and not given (a few seconds: pass them when looping over jobs).
    """
    from loosefit.motion.motions import load_motion

    m = config.motions
    motion = load_motion(
        job.spec,
        avatar,
        fps=config.fps,
        seed=job.seed,
        max_frames=m.max_frames,
        start_frame=m.start_frame,
    )
    if not (unfold and config.unfold.enabled):
        return motion
    from loosefit.motion.pose_correction import unfold_motion

    parts = parts if parts is not None else limb_parts(config, avatar)
    done = unfold_motion(avatar, motion, parts, config.unfold, device=config.cloth.device)
    done.motion.meta["unfold"] = done.stats()
    return done.motion


def limb_parts(config: DatasetConfig, avatar) -> BodyParts:
    """The body parts the pose correction tests: the avatar's, with the arms the cloth
    meets (``config.cloth.colliding_arms``)."""
    from loosefit.body.regions import body_parts

    return body_parts(avatar, arms=config.cloth.colliding_arms)


def group_name(jobs: list[Job]) -> str:
    """A batch's name (its resume file's): a fingerprint of its clips' names and seeds."""
    text = ";".join(f"{j.name}:{j.seed}" for j in jobs)
    return f"batch-{hashlib.sha256(text.encode()).hexdigest()[:12]}"


def unit_name(jobs: list[Job]) -> str:
    """A unit of work's name (its progress reports' and resume file's): a clip's own, or
    its batch's (:func:`group_name`)."""
    return jobs[0].name if len(jobs) == 1 else group_name(jobs)
