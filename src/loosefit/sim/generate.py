"""Making a dataset: many motions simulated with one garment, in parallel, resumably.

``generate(config, out_dir, workers)`` simulates every clip of a
:class:`DatasetConfig`, writes each finished clip atomically, keeps the
manifest up to date after every clip, and on a rerun with the same
configuration skips what is done. Clips whose quality fails the thresholds
(sinking into the body, exploding, NaN) are flagged in the manifest and kept
out of the split rather than silently used.
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime as _dt
import hashlib
import importlib.metadata
import json
import multiprocessing as mp
import os
import platform
import queue
import re
import shutil
import time
import weakref
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from tqdm import tqdm

from loosefit.atomic import atomic_path
from loosefit.body.unfold import UnfoldConfig
from loosefit.data.format import FORMAT, write_json_atomic, write_sequence
from loosefit.errors import LoosefitInputError
from loosefit.eval.quality import PENETRATION_TOLERANCE
from loosefit.garment.dress import DressConfig
from loosefit.garment.fingerprint import cloth_fingerprint
from loosefit.garment.skirt import SkirtConfig
from loosefit.sequence import AnimatedGarment
from loosefit.sim.cloth import ClothConfig, SimulationError, simulate_batch

if TYPE_CHECKING:
    from loosefit.sim.cluster import ClusterConfig


@dataclass
class MotionSource:
    """Where a dataset's motions come from."""

    # "procedural" (random dances), "bvh" (a folder of motion files: BVH, glTF/GLB and
    # SMPL or loosefit .npz, mixed; the name is from when it read only BVH) or "specs" (any
    # motions load_motion reads: files, moves, dance:SECONDS, mirror:..., speed:..., A+B)
    kind: str = "procedural"
    count: int = 8  # procedural: number of dances
    moves: tuple[str, ...] = ()  # procedural: one clip per named move instead of random dances
    seconds: float = 6.0  # procedural: length of each dance
    folder: str = ""  # bvh: the folder of motion files (body.motion_files.motion_files)
    max_frames: int | None = None  # keep at most this many frames of each clip (None: all)
    start_frame: int = 0  # drop the frames of each clip before this one
    test: tuple[str, ...] = ()  # bvh, specs: clip names held out for testing
    specs: tuple[str, ...] = ()  # specs: the motions, one clip each
    chain_test: bool = False  # bvh: the test clips play one after another as one long sequence
    test_every: int = 4  # procedural: every n-th dance is held out for testing
    # bvh: each training clip is also simulated played at these speeds (``NAME_xSPEED``,
    # ``speed:SPEED:FILE``): new dynamics from the same captures; held-out clips never are
    speeds: tuple[float, ...] = ()


@dataclass
class QualityLimits:
    """Thresholds beyond which a simulated clip is flagged and excluded from the split."""

    # garment vertices more than cloth.PENETRATION_TOLERANCE (5 mm) inside the body, worst frame
    max_penetration_fraction: float = 0.01
    max_inside_depth: float = 0.03  # m, no vertex deeper inside the body than this
    max_strain_p99: float = 0.25  # 99th percentile of |edge length / rest - 1|, worst frame
    max_speed: float = 30.0  # m/s, fastest garment vertex


@dataclass
class GarmentFile:
    """A user's garment file, imported onto the avatar (:func:`loosefit.dress.import_garment`)."""

    path: str = ""  # .obj, .gltf, .glb, or a loosefit template .npz (used as it is)
    units: str | None = None  # None: guessed from its size
    up: str | None = None  # None: guessed from its openings
    kind: str | None = None  # "skirt" or "dress"; None: guessed
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)  # m, after placement
    attach: str = "auto"  # "auto", "top", or a text file of vertex indices


GARMENT_TYPES = {"skirt": SkirtConfig, "dress": DressConfig, "file": GarmentFile}


def garment_type(garment) -> str:
    """``skirt``, ``dress`` or ``file``: which of :data:`GARMENT_TYPES` a garment config is."""
    for name, cls in GARMENT_TYPES.items():
        if isinstance(garment, cls):
            return name
    raise LoosefitInputError("DatasetConfig", "garment", f"one of {list(GARMENT_TYPES)}",
                             type(garment).__name__)  # fmt: skip


def make_garment(garment, avatar):
    """The template of a dataset's garment config on ``avatar`` (its rest pose)."""
    from loosefit.dress import fit_dress, fit_skirt, import_garment
    from loosefit.types import GarmentTemplate

    kind = garment_type(garment)
    if kind == "skirt":
        return fit_skirt(avatar, garment)
    if kind == "dress":
        return fit_dress(avatar, garment)
    path = Path(garment.path)
    if path.suffix.lower() == ".npz":
        from loosefit.fit import check_fitted_shape

        template = GarmentTemplate.load(path)
        check_fitted_shape(template, avatar, path)  # a --fit garment: on the body it was fitted to
        return template
    return import_garment(path, avatar, garment.units, garment.up, garment.kind,
                          garment.offset, garment.attach)[0]  # fmt: skip


@dataclass
class DatasetConfig:
    """Everything that decides a dataset's content."""

    preset: str = "custom"  # name of the preset it came from
    # the garment: a parametric skirt or dress, or a user's file
    garment: SkirtConfig | DressConfig | GarmentFile = field(
        default_factory=lambda: SkirtConfig.preset("cpu", "flared")
    )
    cloth: ClothConfig = field(default_factory=ClothConfig)
    motions: MotionSource = field(default_factory=MotionSource)
    limits: QualityLimits = field(default_factory=QualityLimits)
    # capture poses that fold into the body turned a few degrees out of it before simulation
    # (loosefit.body.unfold); data sets made before this field existed were made without
    unfold: UnfoldConfig = field(default_factory=UnfoldConfig)
    fps: float = 30.0  # frame rate of the recorded clips
    seed: int = 0  # seeds the dances and each clip's cloth jitter
    shape: dict = field(default_factory=dict)  # avatar phenotype overrides


PRESETS = ("tiny", "demo", "salsa", "salsa-speed", "salsa-speeds", "dance", "paper", "dress-tiny",
           "dress")  # fmt: skip
# The dance corpus's ballet clips (../shared/mocap/cmu-ballet), and the three held out of
# every training (chosen in issue 34, before any training on ballet: a pirouette with
# expressive arms, an attitude / arabesque with the leg raised, arms held high with the
# upper body turning); the stage account's clips
BALLET_CLIPS = ("05_01", "05_02", "05_03", "05_04", "05_05", "05_06", "05_08", "05_09", "05_10",
                "05_11", "05_12", "05_14", "05_15", "05_16", "05_18", "05_19", "05_20")  # fmt: skip
BALLET_TEST = ("05_02", "05_10", "05_12")


def preset(name: str, bvh_folder: str | None = None) -> DatasetConfig:
    """A named dataset configuration.

    * ``tiny``: seconds, for tests: a coarse skirt, two short moves.
    * ``demo``: the built-in default: procedural dances on the CPU skirt; about
      15 minutes on two CPU cores.
    * ``salsa``: the CMU salsa clips (or any BVH folder), 30 fps, split by clip.
    * ``salsa-speed``: ``salsa``, and its training clips also played 1.25 times as
      fast (the same held-out chain); ``--reuse`` a ``salsa`` folder to simulate
      only the new clips (about an hour on two CPU cores).
    * ``salsa-speeds``: ``salsa-speed``, and the training clips also played 1.5 times as
      fast; ``--reuse`` a ``salsa-speed`` folder to simulate only the 1.5x clips.
    * ``dance``: the salsa clips as ``salsa`` (the same held-out chain) and the 17 ballet
      and modern dance clips of ``cmu-ballet`` beside the salsa folder (three held out,
      :data:`BALLET_TEST`), with the arms colliding (the cloth defaults of the day);
      mirrored at training time (``--mirror``). About 12,500 frames: some 10 hours of
      one CPU core, about 8 minutes of an H100 (docs/BENCHMARKS.md).
    * ``paper``: the paper's scale (a 9,352-vertex skirt, 20 clips, > 10K frames):
      salsa plus procedural dances; meant for a GPU.
    * ``dress-tiny``: ``tiny`` with a coarse strapless dress, for tests.
    * ``dress``: the parametric dress with straps on procedural moves (6 clips of 4 s,
      one held out): a small data set to train a dress on a CPU in about an hour.
    """
    salsa = bvh_folder or str(Path(__file__).resolve().parents[3].parent / "shared/mocap/cmu-salsa")
    salsa_test = ("60_03", "61_03", "60_07", "61_07")
    if name == "tiny":
        return DatasetConfig(
            preset=name,
            garment=SkirtConfig(style="aline", rings=8, segments=24, length=0.45),
            cloth=ClothConfig(
                substeps=8,
                max_substeps=8,
                iterations=4,
                settle_seconds=0.3,
                blend_seconds=0.1,
                self_contact=False,
            ),
            motions=MotionSource(
                kind="procedural",
                moves=("kick", "spin"),
                start_frame=15,  # after the moves' opening half second of standing
                max_frames=12,
                test_every=2,
            ),
        )
    if name == "demo":
        return DatasetConfig(
            preset=name,
            garment=SkirtConfig.preset("cpu", "flared"),
            cloth=ClothConfig(settle_seconds=0.6, blend_seconds=0.4),
            motions=MotionSource(kind="procedural", count=4, seconds=4.0, test_every=4),
        )
    salsa_speeds = {"salsa": (), "salsa-speed": (1.25,), "salsa-speeds": (1.25, 1.5)}
    if name in salsa_speeds:
        return DatasetConfig(
            preset=name,
            garment=SkirtConfig.preset("cpu", "flared"),
            # the arms out of the collision, as the committed set's data was simulated (it
            # stays reproducible by its script); the dance corpus has them (issue 35)
            cloth=ClothConfig(arm_friction=None),
            # from a third of a second in: the captures open with the arms swinging into place
            motions=MotionSource(
                kind="bvh",
                folder=salsa,
                test=salsa_test,
                start_frame=10,
                chain_test=True,
                speeds=salsa_speeds[name],
            ),  # fmt: skip
        )
    if name == "dance":
        ballet = Path(salsa).parent / "cmu-ballet"
        return DatasetConfig(
            preset=name,
            garment=SkirtConfig.preset("cpu", "flared"),
            # a leap's thigh goes up to 8.8 cm into the hips: a clip whose legs fold deeper
            # than 5 cm turns its limbs up to 30 degrees (10 ballet clips; no salsa clip,
            # whose legs fold 4.9 cm at most)
            unfold=UnfoldConfig(deep_degrees=30.0),
            motions=MotionSource(
                kind="bvh",
                folder=salsa,
                specs=tuple(str(ballet / f"{clip}.bvh") for clip in BALLET_CLIPS),
                test=salsa_test + BALLET_TEST,
                start_frame=10,
                chain_test=True,
            ),  # fmt: skip
        )
    if name == "paper":
        return DatasetConfig(
            preset=name,
            garment=SkirtConfig.preset("paper", "flared"),
            cloth=ClothConfig(device="cuda:0"),
            motions=MotionSource(
                kind="bvh", folder=salsa, test=salsa_test, count=6, seconds=60.0, start_frame=10
            ),
        )
    if name == "dress-tiny":
        config = preset("tiny")
        config.preset = name
        config.garment = DressConfig(style="strapless", rings=10, segments=24, length=0.5)
        config.cloth.arm_collision = "upper"
        return config
    if name == "dress":
        return DatasetConfig(
            preset=name,
            garment=DressConfig.preset("cpu", "straps"),
            cloth=ClothConfig(settle_seconds=0.6, blend_seconds=0.4, arm_collision="upper"),
            motions=MotionSource(kind="procedural", count=6, seconds=4.0, test_every=6),
        )
    raise LoosefitInputError("--preset", "preset", "one of " + ", ".join(PRESETS), repr(name))


@dataclass
class Job:
    """One clip to simulate."""

    name: str
    spec: str  # a load_motion spec: a .bvh path, a move name or dance:SECONDS
    seed: int
    test: bool


def plan_jobs(config: DatasetConfig) -> list[Job]:
    """The clips of a dataset, in a fixed order."""
    m = config.motions
    jobs: list[Job] = []
    folder_stems: set[str] = set()  # the clips of a bvh folder
    if m.kind == "bvh" or config.preset == "paper":
        from loosefit.body.motion_files import motion_files

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
        for k, speed in enumerate(m.speeds):
            if not (np.isfinite(speed) and speed > 0 and speed != 1.0):
                raise LoosefitInputError(
                    "MotionSource", "speeds", "positive factors other than 1", m.speeds
                )
            jobs += [
                Job(f"{f.stem}_x{speed:g}", f"speed:{speed:g}:{f}", config.seed + 100 * (k + 1) + i,
                    False)
                for i, f in enumerate(files) if f.stem not in m.test
            ]  # fmt: skip
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
            raise LoosefitInputError("MotionSource", "specs", "motions with distinct names",
                                     f"two named '{dup}'")  # fmt: skip
        unknown = sorted(set(m.test) - set(names) - folder_stems)
        if unknown:
            raise LoosefitInputError("MotionSource", "test",
                                     f"names of the motions {sorted(set(names) | folder_stems)}",
                                     repr(unknown))  # fmt: skip
        jobs += [Job(n, spec, config.seed + 2000 + i, n in m.test)
                 for i, (n, spec) in enumerate(zip(names, m.specs, strict=True))]  # fmt: skip
    if m.kind not in ("bvh", "procedural", "specs"):
        raise LoosefitInputError("MotionSource", "kind", "bvh, procedural or specs",
                                 repr(m.kind))  # fmt: skip
    return jobs


def read_config_file(path: str | Path) -> DatasetConfig:
    """A data set configuration from a YAML (``.yaml``, ``.yml``) or TOML (``.toml``) file:
    the fields of :class:`DatasetConfig`, with ``garment.type`` (``skirt``, ``dress`` or
    ``file``) and, for a parametric garment, an optional ``garment.resolution`` preset
    (``cpu``, ``paper``) that the other garment fields override. What
    ``loosefit simulate --write-config`` writes for any preset reads back as that preset.

    Raises:
        LoosefitInputError: naming the file and the field: an unreadable file, another
            suffix, an unknown field, a bad value.
    """
    path = Path(path)
    if not path.is_file():
        raise LoosefitInputError(path, "<file>", "a data set configuration", "no such file")
    text = path.read_text()
    suffix = path.suffix.lower()
    try:
        if suffix in (".yaml", ".yml"):
            import yaml

            data = yaml.safe_load(text)
        elif suffix == ".toml":
            try:
                import tomllib
            except ImportError:  # Python 3.10
                raise LoosefitInputError(path, "suffix", ".yaml (TOML needs Python 3.11+)",
                                         ".toml") from None  # fmt: skip
            data = tomllib.loads(text)
        else:
            raise LoosefitInputError(path, "suffix", ".yaml, .yml or .toml", repr(path.suffix))
    except LoosefitInputError:
        raise
    except Exception as exc:  # noqa: BLE001 - yaml/toml parse errors of every kind
        raise LoosefitInputError(path, "<file>", f"valid {suffix[1:].upper()}", str(exc)) from exc
    if not isinstance(data, dict):
        raise LoosefitInputError(path, "<file>", "a table of settings", type(data).__name__)
    config = config_from_dict(data, path)
    # files named in it are relative to the file itself
    base = path.resolve().parent
    if isinstance(config.garment, GarmentFile) and config.garment.path:
        config.garment.path = str(base / config.garment.path)
        if config.garment.attach not in ("auto", "top", "none"):
            config.garment.attach = str(base / config.garment.attach)
    if config.motions.folder:
        config.motions.folder = str(base / config.motions.folder)
    config.motions.specs = tuple(_resolve_spec(spec, base) for spec in config.motions.specs)
    return config


def _resolve_spec(spec: str, base: Path) -> str:
    """A motion spec with its relative file paths made relative to ``base``
    (``mirror:a/b.bvh+spin`` -> ``mirror:/base/a/b.bvh+spin``)."""
    parts = []
    for part in spec.split("+"):
        head, _, tail = part.rpartition(":")
        if (
            tail.lower().endswith((".bvh", ".npz", ".gltf", ".glb"))
            and not Path(tail).is_absolute()
        ):
            tail = str(base / tail)
        parts.append(f"{head}:{tail}" if head else tail)
    return "+".join(parts)


def write_config_file(config: DatasetConfig, path: str | Path) -> Path:
    """Write ``config`` as YAML (atomically), for :func:`read_config_file`."""
    import yaml

    path = Path(path)
    if path.suffix.lower() not in (".yaml", ".yml"):
        raise LoosefitInputError(path, "suffix", ".yaml or .yml", repr(path.suffix))
    text = yaml.safe_dump(_normalized(_config_dict(config)), sort_keys=False)
    header = ("# a loosefit data set: `loosefit simulate --config THIS_FILE --out FOLDER`\n"
              "# (fields: loosefit.sim.generate.DatasetConfig; garment.type: skirt, dress or "
              "file)\n")  # fmt: skip
    with atomic_path(path) as tmp:
        tmp.write_text(header + text)
    return path


def spec_name(spec: str) -> str:
    """A clip's name for a motion spec: its file stems and words, safe as a file name
    (``mirror:../a/61_01.bvh`` -> ``mirror_61_01``)."""
    parts = [re.sub(r"\.(bvh|npz|gltf|glb)$", "", re.sub(r"[^:+]*/", "", p))
             for p in spec.split("+")]  # fmt: skip
    parts = [re.sub(r"(units|scale):[^:]*:", "", p) for p in parts]  # how it is read, not what
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", "+".join(parts)).strip("._") or "motion"


def short_spec(spec: str) -> str:
    """A job's motion spec without folders: ``speed:1.25:/x/a.bvh`` -> ``speed:1.25:a.bvh``."""
    return "+".join(re.sub(r"[^:+]*/", "", part) for part in spec.split("+"))


def job_motion(config: DatasetConfig, job: Job, avatar, unfold: bool = True):
    """The motion a job simulates, on ``avatar``'s skeleton at the dataset's frame rate:
    with ``unfold`` (and ``config.unfold.enabled``) the poses that fold into the body
    turned out of it (:func:`~loosefit.body.unfold.unfold_motion`; the correction's
    figures in ``motion.meta["unfold"]``); without, as loaded (the same frame count)."""
    from loosefit.body.motions import load_motion

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
    from loosefit.body.unfold import unfold_motion

    done = unfold_motion(avatar, motion, _limb_parts(config, avatar), config.unfold)
    done.motion.meta["unfold"] = done.stats()
    return done.motion


def _limb_parts(config: DatasetConfig, avatar):
    """The body parts the pose correction tests, built once per avatar and collider (a few
    seconds)."""
    from loosefit.eval.body_regions import body_parts

    arms = config.cloth.colliding_arms
    known = _PARTS.setdefault(avatar, {})
    if arms not in known:
        known[arms] = body_parts(avatar, arms=arms)
    return known[arms]


# job_motion's body parts, per avatar and arm collision
_PARTS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def package_versions() -> dict[str, str]:
    """Versions of the packages that decide a dataset's content."""
    out = {"python": platform.python_version()}
    for pkg in ("loosefit", "torch", "newton", "warp-lang", "anny", "numpy"):
        try:
            out[pkg] = importlib.metadata.version(pkg)
        except importlib.metadata.PackageNotFoundError:
            out[pkg] = "not installed"
    return out


def _config_dict(config: DatasetConfig) -> dict:
    d = asdict(config)
    d["garment"] = {"type": garment_type(config.garment), **d["garment"]}
    return d


def _check_type(source, where: str, value, default) -> None:
    """A configuration value of the kind its field's default is (a number for a number, a
    list of those for a tuple, ...); None where the default is None takes anything plain."""

    def plain(v) -> bool:
        return isinstance(v, bool | int | float | str) or v is None

    if isinstance(default, bool):
        ok = isinstance(value, bool) or (where.endswith("arm_collision") and value == "upper")
    elif isinstance(default, int):
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif isinstance(default, float):
        ok = isinstance(value, int | float) and not isinstance(value, bool)
        ok = ok or (where.endswith("arm_friction") and value is None)  # the arms out
    elif isinstance(default, str):
        ok = isinstance(value, str)
    elif isinstance(default, tuple):
        ok = isinstance(value, list | tuple) and all(plain(v) for v in value)
    elif isinstance(default, dict):
        ok = isinstance(value, dict) and all(isinstance(k, str) and plain(v)
                                             for k, v in value.items())  # fmt: skip
    else:  # None or a nested configuration (checked where it is built)
        ok = plain(value) or dataclasses.is_dataclass(default) or isinstance(value, dict)
    if not ok:
        want = type(default).__name__ if default is not None else "a number or a text"
        raise LoosefitInputError(source, where, f"a value like the default ({want})",
                                 repr(value))  # fmt: skip


def config_from_dict(d: dict, source: str | Path = "dataset config") -> DatasetConfig:
    """A :class:`DatasetConfig` from plain data (a config file, a manifest's ``config``);
    missing fields take their defaults, unknown ones are an error naming them."""

    def build(cls, data, where: str):
        if not isinstance(data, dict):
            raise LoosefitInputError(source, where, "a table of settings", type(data).__name__)
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise LoosefitInputError(source, f"{where}.{unknown[0]}" if where else unknown[0],
                                     f"one of {sorted(names)}", repr(unknown[0]))  # fmt: skip
        defaults = cls()
        for k, v in data.items():
            _check_type(source, f"{where}.{k}" if where else k, v, getattr(defaults, k))
        kwargs = {k: tuple(v) if isinstance(v, list) else v for k, v in data.items()}
        try:
            return cls(**kwargs)
        except LoosefitInputError as exc:
            raise LoosefitInputError(source, f"{where}.{exc.field}", exc.expected, exc.found,
                                     exc.hint) from exc  # fmt: skip
        except TypeError as exc:
            raise LoosefitInputError(source, where, "valid settings", str(exc)) from exc

    d = dict(d)
    g = d.pop("garment", {"type": "skirt", **asdict(SkirtConfig.preset("cpu", "flared"))})
    if not isinstance(g, dict):
        raise LoosefitInputError(source, "garment", "a table of settings", repr(g))
    g = dict(g)
    kind = g.pop("type", "skirt")
    if kind not in GARMENT_TYPES:
        raise LoosefitInputError(source, "garment.type", f"one of {list(GARMENT_TYPES)}",
                                 repr(kind))  # fmt: skip
    resolution = g.pop("resolution", None)
    if resolution is not None and kind != "file":
        style = g.pop("style", "flared" if kind == "skirt" else "straps")
        base = (SkirtConfig if kind == "skirt" else DressConfig).preset(resolution, style)
        g = {**asdict(base), **g}
    sub = {"cloth": ClothConfig, "motions": MotionSource, "limits": QualityLimits,
           "unfold": UnfoldConfig}  # fmt: skip
    parts = {k: build(cls, d.pop(k, {}), k) for k, cls in sub.items()}
    garment = build(GARMENT_TYPES[kind], g, "garment")
    return build(DatasetConfig, {**d, **parts, "garment": garment}, "")


# -- workers -------------------------------------------------------------------------

_WORKER: dict = {}


def _exit_with_parent(poll_seconds: float = 2.0) -> None:
    """In a worker process: exit when the parent dies (a killed run leaves no orphans)."""
    import threading

    parent = os.getppid()

    def watch() -> None:
        while True:
            time.sleep(poll_seconds)
            if os.getppid() != parent:
                os._exit(1)

    threading.Thread(target=watch, daemon=True).start()


@contextlib.contextmanager
def one_torch_thread():
    """Run the block on one torch thread, as every simulation worker does, then give the
    caller back its own count. The avatar's rest shape, and so the garment fitted to it,
    differs in a float's last bit between thread counts (torch's reductions split the work
    differently): built on one thread, the data set's ``template.npz`` is the garment its
    clips were simulated with, whatever the caller's threads."""
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(threads)


def _worker_init(config: DatasetConfig, progress_queue) -> None:
    """Build the avatar and garment once per worker process."""
    import torch

    from loosefit.body.avatar import Avatar, AvatarConfig

    torch.set_num_threads(1)
    avatar = Avatar(AvatarConfig(shape=dict(config.shape)))
    _WORKER.update(avatar=avatar, template=make_garment(config.garment, avatar),
                   queue=progress_queue, config=config)  # fmt: skip


def _pool_worker_init(config: DatasetConfig, progress_queue) -> None:
    """A pool worker: exit with the parent, then build what every clip needs."""
    _exit_with_parent()
    _worker_init(config, progress_queue)


def run_clips(config: DatasetConfig, jobs: list[Job], out_dir: str, resume_every: int = 50,
              progress_queue=None) -> list[dict]:  # fmt: skip
    """Simulate and write one unit of work (:func:`_run_group`) in any process: what a Ray
    task runs (:mod:`loosefit.sim.cluster`). The avatar and garment are built the first
    time the process meets ``config`` and kept for its next units.

    Args:
        progress_queue: anything with ``put((name, frame, total))``, or None.
    """
    if _WORKER.get("config") != config:
        _worker_init(config, progress_queue)
    _WORKER["queue"] = progress_queue
    return _run_group(config, jobs, out_dir, resume_every)


def _run_group(config: DatasetConfig, jobs: list[Job], out_dir: str,
               resume_every: int = 50) -> list[dict]:  # fmt: skip
    """Simulate clips together (one clip, or a batch: :func:`simulate_batch`) and write
    them; returns their manifest entries. The run saves its state in ``out_dir/resume``
    every ``resume_every`` frames and goes on from there when run again after a kill.
    A batch in which one clip diverges is run again clip by clip, so that only that clip
    is flagged."""

    avatar, template, q = _WORKER["avatar"], _WORKER["template"], _WORKER["queue"]
    motions = [job_motion(config, job, avatar) for job in jobs]
    name = unit_name(jobs)
    t0 = time.perf_counter()

    def progress(done: int, total: int) -> None:
        if q is not None:
            q.put((name, done, total))

    resume_dir = Path(out_dir) / "resume"
    resume_dir.mkdir(exist_ok=True)
    try:
        results = simulate_batch(
            avatar, template, motions, config.cloth, progress=progress,
            resume=resume_dir / f"{name}.npz", resume_every=resume_every,
            seeds=[job.seed for job in jobs],
        )  # fmt: skip
    except SimulationError as exc:
        if len(jobs) > 1:
            return [e for job in jobs for e in _run_group(config, [job], out_dir, resume_every)]
        return [_entry(config, jobs[0], motions[0], None, time.perf_counter() - t0, str(exc))]
    for job, motion, result in zip(jobs, motions, results, strict=True):
        write_sequence(
            Path(out_dir) / "sequences" / f"{job.name}.npz",
            AnimatedGarment(dataclasses.replace(motion, name=job.name), template,
                            result.garment_vertices,
                            {"rig": avatar.config.rig, "shape": dict(avatar.shape)},
                            "newton-vbd"),
        )  # fmt: skip
    return [_entry(config, j, m, r) for j, m, r in zip(jobs, motions, results, strict=True)]


def group_name(jobs: list[Job]) -> str:
    """A batch's name (its resume file's): a fingerprint of its clips' names and seeds."""
    text = ";".join(f"{j.name}:{j.seed}" for j in jobs)
    return f"batch-{hashlib.sha256(text.encode()).hexdigest()[:12]}"


def unit_name(jobs: list[Job]) -> str:
    """A unit of work's name (its progress reports' and resume file's): a clip's own, or
    its batch's (:func:`group_name`)."""
    return jobs[0].name if len(jobs) == 1 else group_name(jobs)


def _entry(config: DatasetConfig, job: Job, motion, result, seconds: float = 0.0,
           failure: str = "") -> dict:  # fmt: skip
    """A clip's manifest entry: its result's quality, judged by ``config.limits``
    (``result`` None: the simulation failed with ``failure`` after ``seconds``)."""
    entry = {
        "spec": short_spec(job.spec),
        "seed": job.seed,
        "frames": motion.num_frames,
        "test": job.test,
        # where it was simulated (a data set may be begun on a GPU and finished on the CPU),
        # and under which cloth configuration (DatasetReader.check_uniform)
        "device": config.cloth.device,
        "cloth_fingerprint": cloth_fingerprint(_normalized(asdict(config.cloth))),
    }
    if result is None:
        entry.update(status="flagged", reason=failure, seconds=seconds)
        return entry
    qual = {k: v for k, v in result.quality.items() if np.isscalar(v)}
    lim = config.limits
    problems = []
    if qual.get("nan_count", 0) > 0:
        problems.append(f"{qual['nan_count']} NaN")
    if qual.get("penetration_max", 0.0) > lim.max_penetration_fraction:
        problems.append(
            f"inside the body: {qual['penetration_max']:.3f} of vertices deeper than "
            f"{PENETRATION_TOLERANCE * 1000:.0f} mm in a frame"
        )
    if qual.get("inside_depth_max", 0.0) > lim.max_inside_depth:
        problems.append(f"a vertex {qual['inside_depth_max'] * 100:.1f} cm inside the body")
    if qual.get("strain_p99", 0.0) > lim.max_strain_p99:
        problems.append(f"edge strain p99 {qual['strain_p99']:.3f}")
    if qual.get("max_speed", 0.0) > lim.max_speed:
        problems.append(f"vertex speed {qual['max_speed']:.1f} m/s")
    entry.update(
        status="flagged" if problems else "done",
        reason="; ".join(problems),
        # Simulation time summed over the runs a killed job was resumed in, plus this build
        # (a batch's shared evenly among its clips).
        seconds=result.stats["simulate_seconds"] + result.stats["build_seconds"],
        seconds_per_frame=result.seconds_per_frame,
        substeps_mean=result.stats["substeps_mean"],
        substeps_max=result.stats["substeps_max"],
        batch=result.stats["batch"],
        # the timeline frame a killed run was resumed from (absent: simulated in one go)
        **({"resumed_frame": first} if (first := result.stats.get("resumed_frame")) else {}),
        overlap_frames=result.stats["overlap_frames"],
        overlap_depth_max=result.stats["overlap_depth_max"],
        release_depth=config.cloth.release_depth,
        released_frames=result.stats["released_frames"],
        released_vertices=result.stats["released_vertices"],
        **motion.meta.get("unfold", {}),
        quality=qual,
    )
    return entry


# -- the driver -------------------------------------------------------------------------


class _Direct:
    """A stand-in for a progress queue that calls back at once (single process)."""

    def __init__(self, callback) -> None:
        self.put = lambda item: callback(*item)


def _normalized(d: dict) -> dict:
    return json.loads(json.dumps(d, default=str))


# Cloth fields whose default changed what is simulated: a data set whose manifest lacks one
# was made with this value (not the default).
LEGACY_CLOTH = {
    "flatten_overlaps": False,
    "overlap_inset": 0.002,
    "arm_friction": None,
    "release_depth": None,
}
# Cloth fields a clip can be rechecked for rather than simulated again when they change: the
# release of trapped cloth acts only where cloth is that deep, which a clip's frames show.
RELEASE_FIELDS = ("release_depth",)
LEGACY_UNFOLD = {"enabled": False}  # the same for the pose correction (loosefit.body.unfold)


def _stored_config(manifest: dict) -> dict:
    """A manifest's configuration, with the fields added since it was written at their defaults.

    A dataset made before a field existed is the one made with its default value (or, for
    :data:`LEGACY_CLOTH`'s and :data:`LEGACY_UNFOLD`'s, the value it was made with).
    """

    def fill(old: dict, default: dict) -> dict:
        out = dict(old)
        for key, value in default.items():
            if key not in out:
                out[key] = value
            elif isinstance(value, dict) and isinstance(out[key], dict):
                out[key] = fill(out[key], value)
        return out

    stored = manifest.get("config", {})
    stored = {
        **stored,
        "cloth": {**LEGACY_CLOTH, **stored.get("cloth", {})},
        "unfold": {**LEGACY_UNFOLD, **stored.get("unfold", {})},
    }
    default = _normalized(_config_dict(DatasetConfig()))
    kind = stored.get("garment", {}).get("type", "skirt")
    if kind != "skirt" and kind in GARMENT_TYPES:  # fill a dress's fields from a dress's
        default["garment"] = _normalized({"type": kind, **asdict(GARMENT_TYPES[kind]())})
    return fill(stored, default)


def _refresh_fingerprints(manifest: dict, cloth: dict) -> None:
    """Entries of the manifest's cloth configuration as it was stored take its fingerprint
    with the fields added since at the values they were made with (``cloth``, from
    :func:`_stored_config`): the same configuration, which the manifest is about to store."""
    before = cloth_fingerprint(manifest.get("config", {}).get("cloth", {}))
    after = cloth_fingerprint(cloth)
    for entry in manifest.get("sequences", {}).values():
        if entry.get("cloth_fingerprint") == before:
            entry["cloth_fingerprint"] = after


def _open_manifest(config: DatasetConfig, out: Path) -> dict:
    """A new manifest, or the existing one of the same configuration (resume)."""
    mpath = out / "manifest.json"
    cfg = _normalized(_config_dict(config))
    if mpath.is_file():
        manifest = json.loads(mpath.read_text())
        old = _stored_config(manifest)
        _refresh_fingerprints(manifest, old["cloth"])
        # The device decides no more than the rounding: a data set begun on a GPU goes on on
        # the CPU and vice versa. Each clip's entry notes its device; the manifest's
        # configuration stays the first run's.
        first_device = old["cloth"].get("device", cfg["cloth"]["device"])
        old = {**old, "cloth": {**old["cloth"], "device": cfg["cloth"]["device"]}}
        # A change of the release of trapped cloth alone keeps the clips it never changed
        # (generate checks each; see _recheck_release).
        net = {k: old["cloth"].get(k) for k in RELEASE_FIELDS}
        if old.get("cloth") != cfg.get("cloth") and {
            k: v for k, v in old["cloth"].items() if k not in RELEASE_FIELDS
        } == {k: v for k, v in cfg["cloth"].items() if k not in RELEASE_FIELDS}:
            old = {**old, "cloth": cfg["cloth"]}
            for entry in manifest["sequences"].values():
                for k, v in net.items():
                    entry.setdefault(k, v)
        # A change of the pose correction alone keeps the clips whose motion it leaves as it
        # was (generate checks each; see _recheck_unfold): each entry notes what made it.
        if old.get("unfold") != cfg.get("unfold"):
            for entry in manifest["sequences"].values():
                entry.setdefault("unfold_config", old["unfold"])
            old = {**old, "unfold": cfg["unfold"]}
        if manifest.get("format") != FORMAT or old != cfg:
            diff = sorted(k for k in set(old) | set(cfg) if old.get(k) != cfg.get(k))
            raise LoosefitInputError(
                out,
                "manifest.json",
                f"an empty folder or a dataset of the same configuration (preset {config.preset})",
                f"another dataset (preset {manifest.get('preset')}; differs in {diff})",
                hint="choose another --out folder",
            )
        manifest["config"] = {**cfg, "cloth": {**cfg["cloth"], "device": first_device}}
        return manifest
    if out.exists() and any(out.iterdir()):
        raise LoosefitInputError(
            out, "<folder>", "an empty or new folder", f"{len(list(out.iterdir()))} other entries"
        )
    return {
        "format": FORMAT,
        "preset": config.preset,
        "complete": False,
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "config": cfg,
        "versions": package_versions(),
        "machine": {
            "platform": platform.platform(),
            "processor": platform.processor(),
            "cpu_count": os.cpu_count(),
        },
        "sequences": {},
        "split": {"train": [], "test": []},
    }


def adopt_clips(config: DatasetConfig, jobs: list[Job], manifest: dict, out: Path,
                source: Path) -> list[str]:  # fmt: skip
    """Take the clips ``jobs`` share with another dataset from it instead of simulating them.

    A clip is taken when the other dataset simulated it with the same garment,
    cloth, body, frame rate and seed, from the same motion (spec, seed and frame
    range): its sequence is hard-linked (copied across file systems) and its
    manifest entry copied, marked with where it came from. A clip flagged there
    is taken as flagged (the simulation is deterministic).

    Args:
        config: this dataset's configuration.
        jobs: this dataset's clips.
        manifest: this dataset's manifest (updated in place).
        out: this dataset's folder.
        source: the other dataset's folder.

    Returns:
        The names of the clips taken.
    """
    mpath = source / "manifest.json"
    if not mpath.is_file():
        raise LoosefitInputError(source, "manifest.json", "a dataset folder to reuse clips from",
                                 "no manifest.json")  # fmt: skip
    other = json.loads(mpath.read_text())
    theirs = _stored_config(other)
    ours = _normalized(_config_dict(config))
    their_device = theirs["cloth"].get("device")
    theirs = {**theirs, "cloth": {**theirs["cloth"], "device": ours["cloth"]["device"]}}
    same = ("garment", "cloth", "unfold", "limits", "fps", "seed", "shape")
    clip = ("kind", "folder", "max_frames", "start_frame")
    differs = [k for k in same if theirs.get(k) != ours.get(k)]
    differs += [f"motions.{k}" for k in clip if theirs["motions"].get(k) != ours["motions"][k]]
    if other.get("format") != FORMAT or differs:
        raise LoosefitInputError(
            source, "manifest.json",
            "a dataset simulated like this one (garment, cloth, body, rate, seed, clip range)",
            f"one that differs in {differs or ['format']}",
        )  # fmt: skip
    taken = []
    for job in jobs:
        entry = other["sequences"].get(job.name)
        if job.name in manifest["sequences"] or entry is None:
            continue
        if (
            entry.get("spec") != short_spec(job.spec)
            or entry.get("seed") != job.seed
            or entry.get("test") != job.test
        ):
            continue  # fmt: skip
        src = source / "sequences" / f"{job.name}.npz"
        if entry.get("status") == "done" and src.is_file():
            with atomic_path(out / "sequences" / f"{job.name}.npz") as tmp:
                try:
                    os.link(src, tmp)
                except OSError:
                    shutil.copyfile(src, tmp)
        elif entry.get("status") != "flagged":
            continue  # neither finished nor flagged there: simulate it here
        # a flagged clip is taken as flagged: the simulation is deterministic
        manifest["sequences"][job.name] = {
            **entry, "reused_from": str(source), "device": entry.get("device", their_device),
            "cloth_fingerprint": cloth_fingerprint(ours["cloth"]),  # theirs, as compared above
        }  # fmt: skip
        write_json_atomic(out / "manifest.json", manifest)
        taken.append(job.name)
    return taken


def _recheck(jobs: list[Job], manifest: dict, out: Path, stale, still_right, keep
             ) -> tuple[list[str], list[str]]:  # fmt: skip
    """Clips recorded under another setting, kept or removed to be simulated again.

    Args:
        stale: ``stale(entry)``: whether the clip's entry was made under another setting.
        still_right: ``still_right(job, entry)``: whether this configuration makes the same
            clip (then it is kept).
        keep: ``keep(entry)`` updates a kept clip's entry to this configuration.

    Returns:
        The names of the clips kept and of those removed (their entry and sequence file).
    """
    kept, again = [], []
    for job in jobs:
        entry = manifest["sequences"].get(job.name)
        if entry is None or not stale(entry):
            continue
        if still_right(job, entry):
            keep(entry)
            kept.append(job.name)
        else:
            del manifest["sequences"][job.name]
            (out / "sequences" / f"{job.name}.npz").unlink(missing_ok=True)
            again.append(job.name)
    return kept, again


def _recheck_release(config: DatasetConfig, jobs: list[Job], manifest: dict, out: Path,
                     avatar, template) -> tuple[list[str], list[str]]:  # fmt: skip
    """Clips simulated with another release of trapped cloth, kept or to simulate again.

    A clip recorded under another ``cloth.release_depth`` is the clip this configuration
    makes when the release never acted on it, in either: its entry counts no released
    frames, and the new release finds no cloth that deep in any of its frames
    (:func:`~loosefit.sim.cloth.replay_release` on the collider the simulation met). Such a
    clip is kept (its entry updated); any other (a flagged one too) is removed, to be
    simulated again.

    Returns:
        The names of the clips kept and of those removed.
    """
    from loosefit.data.format import read_sequence
    from loosefit.sim.cloth import (
        TrappedRelease,
        collider_meshes,
        collider_parts,
        release_parts,
        replay_release,
        timeline,
    )

    depth, cloth = config.cloth.release_depth, config.cloth
    fingerprint = cloth_fingerprint(_normalized(asdict(cloth)))  # a kept clip's
    built: dict = {}  # the collider's parts and meshes, for the first clip to replay

    def still_right(job: Job, entry: dict) -> bool:
        path = out / "sequences" / f"{job.name}.npz"
        if entry.get("status") != "done" or entry.get("released_frames") or not path.exists():
            return False
        if depth is None:
            return True
        if not built:
            built.update(parts=collider_parts(avatar, cloth),
                         meshes=collider_meshes(avatar, cloth)[2])  # fmt: skip
        motion = job_motion(config, job, avatar)
        line = timeline(avatar, motion, cloth, built["parts"])
        garment = read_sequence(path, template).garment_vertices
        release = TrappedRelease(
            line.collider[0], built["meshes"], release_parts(built["parts"]),
            template.num_vertices, depth, cloth.body_contact_distance,
        )  # fmt: skip
        return replay_release(garment, line.collider[line.n_pre :], release, 1.0 / motion.fps) == 0

    return _recheck(
        jobs, manifest, out,
        stale=lambda entry: entry.get("release_depth", depth) != depth,
        still_right=still_right,
        keep=lambda entry: entry.update(release_depth=depth, released_frames=0,
                                        released_vertices=0, cloth_fingerprint=fingerprint),
    )  # fmt: skip


def _recheck_unfold(config: DatasetConfig, jobs: list[Job], manifest: dict, out: Path,
                    avatar) -> tuple[list[str], list[str]]:  # fmt: skip
    """Clips simulated under another pose correction, kept or to simulate again.

    A clip whose entry notes another ``unfold_config`` (:func:`_open_manifest`) is the clip
    this configuration makes when both corrections give it the same motion, frame for frame
    (:func:`~loosefit.body.unfold.same_correction`: a cap raised for deep folds leaves a clip
    without them as it was). Such a clip is kept (a flagged one stays flagged: the simulation
    is deterministic); any other is removed, to be simulated again.

    Returns:
        The names of the clips kept and of those removed.
    """
    from loosefit.body.unfold import same_correction

    known = {f.name for f in dataclasses.fields(UnfoldConfig)}

    def still_right(job: Job, entry: dict) -> bool:
        stored = UnfoldConfig(**{k: v for k, v in entry["unfold_config"].items() if k in known})
        motion = job_motion(config, job, avatar, unfold=False)
        parts = _limb_parts(config, avatar)
        return same_correction(avatar, motion, parts, stored, config.unfold)

    return _recheck(
        jobs, manifest, out,
        stale=lambda entry: "unfold_config" in entry,
        still_right=still_right,
        keep=lambda entry: entry.pop("unfold_config"),
    )  # fmt: skip


def generate(
    config: DatasetConfig,
    out_dir: str | Path,
    workers: int = 1,
    progress: bool = True,
    reuse: str | Path | None = None,
    batch: int = 1,
    resume_every: int = 50,
    cluster: ClusterConfig | None = None,
) -> dict:
    """Simulate a dataset into ``out_dir`` (resuming a run of the same configuration).

    Args:
        config: what to simulate.
        out_dir: the dataset folder (new, empty, or holding the same configuration).
        workers: parallel simulations (one CPU core each on the CPU); with ``cluster``,
            the CPUs of a Ray instance it starts on this machine when it finds none.
        batch: clips simulated at once, each a world of one Newton model
            (:func:`~loosefit.sim.cloth.simulate_batch`): for a GPU, where 16 clips
            cost little more than one. Clips of similar length go together.
        progress: show a progress bar over frames with rate and ETA.
        reuse: another dataset folder whose clips of the same simulation are
            taken rather than simulated again (:func:`adopt_clips`).
        resume_every: frames between the saves of a clip's state in ``out_dir/resume``,
            from which a killed run goes on.
        cluster: run every unit of work as a task on this Ray cluster
            (:func:`loosefit.sim.cluster.run_on_ray`; ``out_dir`` on storage every node
            shares) instead of in processes of this machine; the data set is the same.

    Returns:
        The final manifest (also written to ``out_dir/manifest.json``).
    """
    from loosefit.body.avatar import Avatar, AvatarConfig
    from loosefit.dress import collider_arms

    if cluster is not None:  # no ray, or no cluster at the address: now, before any work
        from loosefit.sim.cluster import preflight

        preflight(cluster)
    out = Path(out_dir)
    jobs = plan_jobs(config)
    manifest = _open_manifest(config, out)
    (out / "sequences").mkdir(parents=True, exist_ok=True)
    for stale in (out / "sequences").glob("*.partial.npz"):
        stale.unlink()  # left by a killed run: never a whole sequence

    with one_torch_thread():
        avatar = Avatar(AvatarConfig(shape=dict(config.shape)))
        template = make_garment(config.garment, avatar)
    if collider_arms(template) == "upper" and config.cloth.arm_collision is False:
        raise LoosefitInputError(
            "DatasetConfig", "cloth.arm_collision", "'upper' (or true) for a dress: its bodice "
            "reaches the arms", "false", hint="set cloth.arm_collision = 'upper'",
        )  # fmt: skip
    template.save(out / "template.npz")
    manifest["body"] = {
        "model": "anny",
        "rig": avatar.config.rig,
        "shape": avatar.shape,
        "floor_height": avatar.floor_height,
    }
    manifest["garment"] = {"name": template.name, "num_vertices": template.num_vertices}
    write_json_atomic(out / "manifest.json", manifest)
    if reuse is not None:
        taken = adopt_clips(config, jobs, manifest, out, Path(reuse))
        if progress and taken:
            tqdm.write(f"reused {len(taken)} clips from {reuse}: {', '.join(taken)}")
    kept, again = _recheck_unfold(config, jobs, manifest, out, avatar)
    if kept or again:
        write_json_atomic(out / "manifest.json", manifest)
        if progress:
            tqdm.write(
                f"the pose correction changed: kept {', '.join(kept) or 'none'} (their "
                f"motion is the same); simulating again {', '.join(again) or 'none'}"
            )
    kept, again = _recheck_release(config, jobs, manifest, out, avatar, template)
    if kept or again:
        write_json_atomic(out / "manifest.json", manifest)
        if progress:
            tqdm.write(f"release_depth changed to {config.cloth.release_depth}: kept "
                       f"{', '.join(kept) or 'none'} (it never acts on them); simulating "
                       f"again {', '.join(again) or 'none'}")  # fmt: skip

    done = {
        n for n, e in manifest["sequences"].items()
        if e.get("status") == "flagged" or (out / "sequences" / f"{n}.npz").is_file()
    }  # fmt: skip
    todo = [j for j in jobs if j.name not in done]
    if not (isinstance(batch, int) and batch >= 1):
        raise LoosefitInputError("generate", "batch", "an integer >= 1", repr(batch))
    if not (isinstance(resume_every, int) and resume_every >= 1):
        raise LoosefitInputError("generate", "resume_every", "an integer >= 1",
                                 repr(resume_every))  # fmt: skip
    # Frames to simulate per clip (settle and blend included), for the bar's ETA.
    preroll = round((config.cloth.settle_seconds + config.cloth.blend_seconds) * config.fps)
    length = {j.name: job_motion(config, j, avatar, unfold=False).num_frames + preroll
              for j in todo}  # fmt: skip
    # The units of work: clips alone, or batches of clips of similar length (longest first).
    if batch > 1:
        ordered = sorted(todo, key=lambda j: (-length[j.name], j.name))
        groups = [ordered[i : i + batch] for i in range(0, len(ordered), batch)]
    else:
        groups = [[j] for j in todo]
    name_of = [unit_name(g) for g in groups]
    frames_of = {n: max(length[j.name] for j in g) for n, g in zip(name_of, groups, strict=True)}
    bar = tqdm(
        total=sum(frames_of.values()),
        unit="frame",
        desc=f"simulate {config.preset} ({len(todo)} clips"
        + (f", {batch} at once)" if batch > 1 else ")"),
        disable=not progress,
        smoothing=0.05,
    )
    seen: dict[str, int] = {}  # the last frame each unit of work reported
    resumed: dict[str, int] = {}  # the frames each found on disk (not this run's work)

    def on_progress(name: str, k: int, total: int) -> None:
        if name not in seen:  # a resumed unit first reports the frame after its last saved
            resumed[name] = seen[name] = k - 1
        elif k <= seen[name]:  # run again from its last save (a Ray task whose worker died):
            resumed[name] -= seen[name] - (k - 1)  # the frames done twice are work done twice
            seen[name] = k - 1
        if frames_of.get(name) != total - resumed[name]:  # the estimate was off: correct it
            frames_of[name] = total - resumed[name]
            bar.total = sum(frames_of.values())
            bar.refresh()
        bar.update(k - seen[name])
        seen[name] = k

    def record(group: list[Job], entries: list[dict]) -> None:
        for job, entry in zip(group, entries, strict=True):
            manifest["sequences"][job.name] = entry
            if entry["status"] == "flagged":
                tqdm.write(f"flagged {job.name}: {entry['reason']}")
        write_json_atomic(out / "manifest.json", manifest)

    # Longest first, so that no long clip starts last and runs alone.
    by_length = [g for _, g in sorted(zip(name_of, groups, strict=True),
                                      key=lambda ng: -frames_of[ng[0]])]  # fmt: skip
    if cluster is not None:
        from loosefit.sim.cluster import run_on_ray

        created = manifest.get("created", "")
        run_on_ray(cluster, config, by_length, str(out), resume_every, created, on_progress,
                   record, local_cpus=workers)  # fmt: skip
    elif workers <= 1:
        with one_torch_thread():  # in this process: its thread count is the caller's again
            _worker_init(config, _Direct(on_progress))
            for group in groups:
                record(group, _run_group(config, group, str(out), resume_every))
    else:
        ctx = mp.get_context("spawn")
        with ctx.Manager() as manager:
            q = manager.Queue()
            with ProcessPoolExecutor(
                max_workers=workers,
                mp_context=ctx,
                initializer=_pool_worker_init,
                initargs=(config, q),
            ) as pool:
                futures = {pool.submit(_run_group, config, g, str(out), resume_every): g
                           for g in by_length}  # fmt: skip
                pending = set(futures)
                while pending:
                    finished = {f for f in pending if f.done()}
                    while True:
                        try:
                            on_progress(*q.get(timeout=0.2))
                        except queue.Empty:
                            break
                    for f in finished:
                        record(futures[f], f.result())
                    pending -= finished
    bar.close()

    ok = [j for j in jobs if manifest["sequences"].get(j.name, {}).get("status") == "done"]
    manifest["split"] = {
        "train": [j.name for j in ok if not j.test],
        "test": [j.name for j in ok if j.test],
    }
    manifest["excluded"] = [
        n for n, e in manifest["sequences"].items() if e.get("status") != "done"
    ]
    manifest["summary"] = summarize(manifest)
    manifest["complete"] = True
    write_json_atomic(out / "manifest.json", manifest)
    return manifest


def summarize(manifest: dict) -> dict:
    """Totals and worst quality figures over the clips the dataset keeps.

    Flagged clips count in ``clips`` and in the cost (``seconds_per_frame_mean``,
    over every simulated clip) but not in the frames or the quality figures: those
    describe the data a model trains and is judged on.
    """
    simulated = [e for e in manifest["sequences"].values() if "quality" in e]
    entries = [e for e in simulated if e["status"] == "done"]
    frames = sum(e["frames"] for e in entries)
    spf = [e["seconds_per_frame"] for e in simulated]
    timed = [e["seconds"] for e in simulated if "seconds" in e]

    def worst(key: str) -> float:
        return max((e["quality"].get(key, 0.0) for e in entries), default=0.0)

    return {
        "clips": len(manifest["sequences"]),
        "clips_ok": sum(e["status"] == "done" for e in manifest["sequences"].values()),
        "frames": frames,
        "seconds_per_frame_mean": float(np.mean(spf)) if spf else None,
        # clips of this data set's length simulated per hour (a batch's time shared out)
        "clips_per_hour": 3600.0 * len(timed) / sum(timed) if sum(timed) > 0 else None,
        "inside_max": worst("inside_max"),
        "penetration_max": worst("penetration_max"),
        "inside_depth_max": worst("inside_depth_max"),
        "inside_mean": float(np.mean([e["quality"].get("inside_mean", 0) for e in entries]))
        if entries
        else None,
        "strain_p99_max": worst("strain_p99"),
        "max_speed": worst("max_speed"),
        "nan_count": int(sum(e["quality"].get("nan_count", 0) for e in entries)),
    }


def _devices(manifest: dict) -> list[str]:
    """The devices the clips were simulated on (an entry without one: the manifest's)."""
    default = manifest.get("config", {}).get("cloth", {}).get("device", "cpu")
    return sorted({e.get("device", default) for e in manifest["sequences"].values()} or {default})


def format_report(manifest: dict) -> str:
    """A plain-text table of each clip's quality, for the end of a run.

    Columns: the share of garment vertices inside the body (mean over frames, and the
    worst frame), the worst frame's share deeper than 5 mm, the deepest vertex, the edge
    strain p99, the fastest vertex, the frames whose capture pose was turned out of the body
    (:mod:`loosefit.body.unfold`, with the largest turn), and the frames in which the pose
    still folds into itself (a limb inside the rest of the body, with how deep), where
    cloth is pinched.
    """
    width = max([14, *(len(n) + 2 for n in manifest["sequences"])])
    lines = [
        f"{'clip':<{width}}{'split':<7}{'frames':>7}{'s/frame':>9}{'inside mean':>13}"
        f"{'inside max':>12}{'> 5 mm':>8}{'depth cm':>10}{'strain p99':>12}{'speed':>8}"
        f"{'turned':>14}{'folds':>12}  status"
    ]
    folding = []
    for name, e in manifest["sequences"].items():
        q = e.get("quality", {})
        n_fold = e.get("overlap_frames")
        if n_fold:
            folding.append(name)
            folds = f"{n_fold}, {100 * e.get('overlap_depth_max', 0.0):.1f} cm"
        else:
            folds = "-" if n_fold is None else "0"
        n_turn = e.get("unfold_frames")
        turned = "-" if n_turn is None else "0"
        if n_turn:
            turned = f"{n_turn}, {e.get('unfold_degrees_max', 0.0):.1f} deg"
        lines.append(
            f"{name:<{width}}{'test' if e.get('test') else 'train':<7}{e.get('frames', 0):>7}"
            f"{e.get('seconds_per_frame', float('nan')):>9.2f}"
            f"{q.get('inside_mean', float('nan')):>13.5f}"
            f"{q.get('inside_max', float('nan')):>12.4f}"
            f"{q.get('penetration_max', float('nan')):>8.4f}"
            f"{100 * q.get('inside_depth_max', float('nan')):>10.2f}"
            f"{q.get('strain_p99', float('nan')):>12.3f}"
            f"{q.get('max_speed', float('nan')):>8.2f}{turned:>14}{folds:>12}  {e['status']}"
            + (f" ({e['reason']})" if e.get("reason") else "")
        )
    s = manifest.get("summary", {})
    lines.append(
        f"{s.get('clips_ok', 0)}/{s.get('clips', 0)} clips kept, {s.get('frames', 0)} frames; "
        f"split {len(manifest['split']['train'])} train / {len(manifest['split']['test'])} test"
    )
    if s.get("clips_per_hour"):
        lines.append(
            f"{s['seconds_per_frame_mean']:.3f} s per frame per clip, "
            f"{s['clips_per_hour']:.1f} clips per hour "
            f"(device {', '.join(_devices(manifest))})"
        )
    if folding:
        lines.append(
            f"the body folds into itself (a limb inside the rest of it) in {len(folding)} "
            f"clip(s): cloth caught there is pinched; where and how deep: loosefit diagnose "
            f"DATASET {folding[0]} (docs/PENETRATION.md)"
        )
    return "\n".join(lines)
