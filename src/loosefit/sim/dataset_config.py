"""A data set's configuration: :class:`DatasetConfig` and its parts, read from and written
to YAML or TOML files, unknown fields an error naming them.

The named configurations (``--preset``) are :mod:`loosefit.sim.presets`.
"""

from __future__ import annotations

import dataclasses
import json
import numbers
from dataclasses import asdict, dataclass, field
from pathlib import Path

from loosefit.atomic import atomic_path
from loosefit.errors import LoosefitInputError
from loosefit.garment.dress import DressConfig
from loosefit.garment.skirt import SkirtConfig
from loosefit.motion.pose_correction import UnfoldConfig
from loosefit.sim.cloth_config import ClothConfig


@dataclass
class MotionSource:
    """Where a dataset's motions come from."""

    # "procedural" (random dances), "bvh" (a folder of motion files of any format) or "specs"
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
    # bvh: the speeds each training clip is also played at (NAME_xSPEED; held-out clips never)
    speeds: tuple[float, ...] = ()
    # bvh: the clips played at ``speeds``, folder files and specs alike (empty: every folder
    # file not held out); naming them keeps clips a data set leaves out of training (its
    # validation clips) from coming back retimed
    speed_clips: tuple[str, ...] = ()
    # bvh: the pelvis pitches (degrees added, positive raises its front) each of
    # ``pitch_clips`` is also danced at (NAME_pitchDEG; held-out clips never); the same steps
    # at another pitch of the pelvis, the spine and legs as captured
    # (loosefit.motion.pelvis.pitch_pelvis)
    pitches: tuple[float, ...] = ()
    # bvh: the clips danced at ``pitches``, folder files and specs alike (empty: every folder
    # file not held out)
    pitch_clips: tuple[str, ...] = ()
    # bvh: the spins each of ``spin_clips`` is also danced with, on the spot: a rate (turns
    # a second at each spin's peak, the sign the first spin's direction; NAME_spinTURNS) or
    # the spec's field "TURNS,ramp=SECONDS,hold=SECONDS" (NAME_spinTURNS_rampS_holdS); held-out
    # clips never (loosefit.motion.spin.spin_motion)
    spins: tuple[float | str, ...] = ()
    # bvh: the clips danced at ``spins``, folder files and specs alike (empty: every folder
    # file not held out)
    spin_clips: tuple[str, ...] = ()


@dataclass
class QualityLimits:
    """Thresholds beyond which a simulated clip is flagged and excluded from the split."""

    # fraction of garment vertices over 5 mm inside the body (PENETRATION_TOLERANCE), worst frame
    max_penetration_fraction: float = 0.01
    max_inside_depth: float = 0.03  # m, no vertex deeper inside the body than this
    max_strain_p99: float = 0.25  # 99th percentile of |edge length / rest - 1|, worst frame
    max_speed: float = 30.0  # m/s, fastest garment vertex


@dataclass
class GarmentFile:
    """A user's garment file, imported onto the avatar
    (:func:`loosefit.fitting.place.import_garment`)."""

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
    raise LoosefitInputError(
        "DatasetConfig", "garment", f"one of {list(GARMENT_TYPES)}", type(garment).__name__
    )


def make_garment(garment, avatar):
    """The template of a dataset's garment config on ``avatar`` (its rest pose)."""
    from loosefit.fitting.place import check_fitted_shape, fit_dress, fit_skirt, import_garment
    from loosefit.types import GarmentTemplate

    kind = garment_type(garment)
    if kind == "skirt":
        return fit_skirt(avatar, garment)
    if kind == "dress":
        return fit_dress(avatar, garment)
    path = Path(garment.path)
    if path.suffix.lower() == ".npz":
        template = GarmentTemplate.load(path)
        check_fitted_shape(template, avatar, path)  # a --fit garment: on the body it was fitted to
        return template
    return import_garment(
        path,
        avatar,
        garment.units,
        garment.up,
        garment.kind,
        garment.offset,
        attach=garment.attach,
    )[0]


@dataclass
class DatasetConfig:
    """Everything that decides a dataset's content.

    With ``seeds``, the data set is an ensemble: each clip is simulated once per seed, each
    run a member of the clip's ensemble. The members share the clip's motion, frame for
    frame, and differ only in the jitter of the cloth's start, drawn from each member's
    seed (how they are named and seeded: :func:`loosefit.sim.jobs.plan_jobs`).
    """

    preset: str = "custom"  # name of the preset it came from
    # the garment: a parametric skirt or dress, or a user's file
    garment: SkirtConfig | DressConfig | GarmentFile = field(
        default_factory=lambda: SkirtConfig.preset("cpu", "flared")
    )
    cloth: ClothConfig = field(default_factory=ClothConfig)  # how the garment is simulated
    motions: MotionSource = field(default_factory=MotionSource)  # which clips are simulated
    limits: QualityLimits = field(default_factory=QualityLimits)  # when a clip is flagged
    # how capture poses that fold into the body are turned out of it (pose_correction)
    unfold: UnfoldConfig = field(default_factory=UnfoldConfig)
    fps: float = 30.0  # frame rate of the recorded clips
    seed: int = 0  # seeds the dances and each clip's cloth jitter
    shape: dict = field(default_factory=dict)  # avatar phenotype overrides
    # an ensemble's member seeds (distinct integers >= 0, one run of each clip each); None: one
    seeds: list[int] | None = None

    def __post_init__(self) -> None:
        self.seeds = check_seeds(self.seeds)


def check_seeds(seeds, source: str | Path = "DatasetConfig") -> list[int] | None:
    """An ensemble's member seeds (``DatasetConfig.seeds``) as a list, checked: None, or
    distinct integers >= 0, at least one.

    Raises:
        LoosefitInputError: naming ``source`` and ``seeds``, what was expected and what
            was found (an empty list, a repeated seed, a negative one, one not an integer).
    """
    if seeds is None:
        return None
    expected = "distinct integers >= 0"
    if isinstance(seeds, str | bytes) or not isinstance(seeds, list | tuple):
        raise LoosefitInputError(source, "seeds", f"a list of {expected}", repr(seeds))
    if not seeds:
        raise LoosefitInputError(
            source, "seeds", "at least one seed (no ensemble: leave seeds out)", "an empty list"
        )
    for s in seeds:
        if isinstance(s, bool) or not isinstance(s, numbers.Integral):
            raise LoosefitInputError(source, "seeds", expected, f"{s!r} in {list(seeds)}")
        if s < 0:
            raise LoosefitInputError(source, "seeds", expected, f"{s} in {list(seeds)}")
    twice = next((s for i, s in enumerate(seeds) if s in seeds[:i]), None)
    if twice is not None:
        raise LoosefitInputError(source, "seeds", expected, f"{twice} twice in {list(seeds)}")
    return [int(s) for s in seeds]


def config_dict(config: DatasetConfig) -> dict:
    """``config`` as plain data: its fields, the garment's with its ``type``."""
    d = asdict(config)
    d["garment"] = {"type": garment_type(config.garment), **d["garment"]}
    return d


def normalized(d: dict) -> dict:
    """Plain data as JSON stores it (tuples as lists, anything else as text)."""
    return json.loads(json.dumps(d, default=str))


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
        ok = isinstance(value, dict) and all(
            isinstance(k, str) and plain(v) for k, v in value.items()
        )
    elif where == "seeds":  # a list (None: no ensemble), checked by check_seeds
        ok = True
    else:  # None or a nested configuration (checked where it is built)
        ok = plain(value) or dataclasses.is_dataclass(default) or isinstance(value, dict)
    if not ok:
        want = type(default).__name__ if default is not None else "a number or a text"
        raise LoosefitInputError(source, where, f"a value like the default ({want})", repr(value))


def config_from_dict(d: dict, source: str | Path = "dataset config") -> DatasetConfig:
    """A :class:`DatasetConfig` from plain data (a config file, a manifest's ``config``);
    missing fields take their defaults, unknown ones are an error naming them."""

    def build(cls, data, where: str):
        if not isinstance(data, dict):
            raise LoosefitInputError(source, where, "a table of settings", type(data).__name__)
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise LoosefitInputError(
                source,
                f"{where}.{unknown[0]}" if where else unknown[0],
                f"one of {sorted(names)}",
                repr(unknown[0]),
            )
        defaults = cls()
        for k, v in data.items():
            _check_type(source, f"{where}.{k}" if where else k, v, getattr(defaults, k))
        kwargs = {k: tuple(v) if isinstance(v, list) else v for k, v in data.items()}
        try:
            return cls(**kwargs)
        except LoosefitInputError as exc:
            field_ = f"{where}.{exc.field}" if where else exc.field
            raise LoosefitInputError(source, field_, exc.expected, exc.found, exc.hint) from exc
        except TypeError as exc:
            raise LoosefitInputError(source, where, "valid settings", str(exc)) from exc

    d = dict(d)
    g = d.pop("garment", {"type": "skirt", **asdict(SkirtConfig.preset("cpu", "flared"))})
    if not isinstance(g, dict):
        raise LoosefitInputError(source, "garment", "a table of settings", repr(g))
    g = dict(g)
    kind = g.pop("type", "skirt")
    if kind not in GARMENT_TYPES:
        raise LoosefitInputError(
            source, "garment.type", f"one of {list(GARMENT_TYPES)}", repr(kind)
        )
    resolution = g.pop("resolution", None)
    if resolution is not None and kind != "file":
        style = g.pop("style", "flared" if kind == "skirt" else "straps")
        base = (SkirtConfig if kind == "skirt" else DressConfig).preset(resolution, style)
        g = {**asdict(base), **g}
    sub = {
        "cloth": ClothConfig,
        "motions": MotionSource,
        "limits": QualityLimits,
        "unfold": UnfoldConfig,
    }
    parts = {k: build(cls, d.pop(k, {}), k) for k, cls in sub.items()}
    garment = build(GARMENT_TYPES[kind], g, "garment")
    return build(DatasetConfig, {**d, **parts, "garment": garment}, "")


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
                raise LoosefitInputError(
                    path, "suffix", ".yaml (TOML needs Python 3.11+)", ".toml"
                ) from None
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
    config.motions.specs = tuple(resolve_spec(spec, base) for spec in config.motions.specs)
    return config


def resolve_spec(spec: str, base: Path) -> str:
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
    text = yaml.safe_dump(normalized(config_dict(config)), sort_keys=False)
    header = (
        "# a loosefit data set: `loosefit simulate --config THIS_FILE --out FOLDER`\n"
        "# (fields: loosefit.sim.dataset_config.DatasetConfig; garment.type: skirt, dress or "
        "file)\n"
    )
    with atomic_path(path) as tmp:
        tmp.write_text(header + text)
    return path
