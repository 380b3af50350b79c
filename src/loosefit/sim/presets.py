"""The named data set configurations (``loosefit simulate --preset NAME``), as data.

Each preset is a table in the form of a configuration file (the fields of
:class:`~loosefit.sim.dataset_config.DatasetConfig`, read by
:func:`~loosefit.sim.dataset_config.config_from_dict`, so an unknown field is an error);
fields not given take their defaults. Two placeholders stand for folders known only when
the preset is built: ``{salsa}``, the folder of the CMU salsa clips (``--bvh``, by default
``../shared/mocap/cmu-salsa`` beside the repository), and ``{ballet}``, the
``cmu-ballet`` folder beside it.

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
  one CPU core, about 8 minutes of an H100 (docs/results/BENCHMARKS.md).
* ``dance-speed``: ``dance``, and its seven ballet training clips (:data:`BALLET_TRAIN`)
  also played 1.25 and 0.8 times as fast (``05_01_x1.25``, ``05_01_x0.8``; 2,700 frames
  more, the ballet training frames three times over); ``--reuse`` a ``dance`` folder to
  simulate only those (about an hour of one CPU core).
* ``dance-pitch``: ``dance``, and its seven ballet training clips also danced with the
  pelvis pitched 10 degrees up and 10 down, the spine and legs as captured
  (``05_01_pitch10``, ``05_01_pitch-10``; 2,700 frames more): the same steps at the
  pelvis pitches the captures disagree on (salsa 3-9 degrees below the horizontal, ballet
  10-30); ``--reuse`` a ``dance`` folder to simulate only those (about two core-hours).
* ``dance-spin``: ``dance``, and its seven ballet training clips also danced with spins on
  the spot added, one turn a second at each spin's peak, a spin every 3 s, alternately left
  and right (``05_01_spin1``; 1,330 frames more): turns from every pose of the ballet, where
  the captures hold a few turns from the poses their dancers turned from; ``--reuse`` a
  ``dance`` folder to simulate only those.
* ``dance-spins``: ``dance-spin``, and the same seven clips with spins peaking at half a
  turn a second (``05_01_spin0.5``; 1,330 frames more): the flare a slower turn builds, so
  that a model learns how the flare grows with the rate rather than that a turn flares;
  ``--reuse`` a ``dance-spin`` folder to simulate only those.
* ``dance-spins-slow``: ``dance-spins``, and the same seven clips with spins that build as
  a dancer's do: the rate rising over 0.8 s to one turn a second and falling back at once
  (``05_01_spin1_ramp0.8_hold0``, ``spin:1,ramp=0.8,hold=0:``; 1,330 frames more), where
  the others rise in 0.4 s and hold 0.8 s; ``--reuse`` a ``dance-spins`` folder to simulate
  only those.
* ``dance-turns``: ``dance-spins-slow``, and the same seven clips with flicks: brief turns
  rising over 0.25 s to two turns a second and falling back at once, half a turn each, one
  every 1.9 s (``05_01_spin2_ramp0.25_hold0``; 1,330 frames more): a turn that is fast but
  over before the skirt can flare far, beside the long ones that flare it; ``--reuse`` a
  ``dance-spins-slow`` folder to simulate only those.
* ``paper``: the paper's scale (a 9,352-vertex skirt, 20 clips, > 10K frames):
  salsa plus procedural dances; meant for a GPU.
* ``dress-tiny``: ``tiny`` with a coarse strapless dress, for tests.
* ``dress``: the parametric dress with straps on procedural moves (6 clips of 4 s,
  one held out): a small data set to train a dress on a CPU in about an hour.
"""

from __future__ import annotations

import copy
from pathlib import Path

from loosefit.errors import LoosefitInputError
from loosefit.sim.dataset_config import DatasetConfig, config_from_dict

# The salsa clips held out of every training, played one after another as one sequence.
SALSA_TEST = ("60_03", "61_03", "60_07", "61_07")
# The dance corpus's ballet clips (../shared/mocap/cmu-ballet), and the three held out of
# every training (chosen before any training on ballet: a pirouette with expressive arms,
# an attitude / arabesque with the leg raised, arms held high with the upper body
# turning); the stage account's clips
BALLET_CLIPS = (
    "05_01",
    "05_02",
    "05_03",
    "05_04",
    "05_05",
    "05_06",
    "05_08",
    "05_09",
    "05_10",
    "05_11",
    "05_12",
    "05_14",
    "05_15",
    "05_16",
    "05_18",
    "05_19",
    "05_20",
)
BALLET_TEST = ("05_02", "05_10", "05_12")
# The ballet clips the dance corpus trains on: its simulator flagged the others (05_05,
# 05_06, 05_08, 05_14, 05_16, 05_18, 05_19), which left them out of the split and made them
# the validation clips; ``dance-speed`` retimes these seven only, so that no validation
# motion comes back into training at another speed
BALLET_TRAIN = ("05_01", "05_03", "05_04", "05_09", "05_11", "05_15", "05_20")

CPU_SKIRT = {"type": "skirt", "resolution": "cpu", "style": "flared"}

_TINY = {
    "garment": {"type": "skirt", "style": "aline", "rings": 8, "segments": 24, "length": 0.45},
    "cloth": {
        "substeps": 8,
        "max_substeps": 8,
        "iterations": 4,
        "settle_seconds": 0.3,
        "blend_seconds": 0.1,
        "self_contact": False,
    },
    "motions": {
        "kind": "procedural",
        "moves": ("kick", "spin"),
        "start_frame": 15,  # after the moves' opening half second of standing
        "max_frames": 12,
        "test_every": 2,
    },
}


def _salsa(speeds: tuple[float, ...]) -> dict:
    """The salsa clips, each training clip also played at ``speeds``."""
    return {
        "garment": CPU_SKIRT,
        # the arms out of the collision, as the committed set's data was simulated (it
        # stays reproducible by its script); the dance corpus has them (a frictionless
        # collider of their own, ClothConfig.arm_friction)
        "cloth": {"arm_friction": None},
        # from a third of a second in: the captures open with the arms swinging into place
        "motions": {
            "kind": "bvh",
            "folder": "{salsa}",
            "test": SALSA_TEST,
            "start_frame": 10,
            "chain_test": True,
            "speeds": speeds,
        },
    }


def _dance(
    speeds: tuple[float, ...] = (),
    speed_clips: tuple[str, ...] = (),
    pitches: tuple[float, ...] = (),
    pitch_clips: tuple[str, ...] = (),
    spins: tuple[float | str, ...] = (),
    spin_clips: tuple[str, ...] = (),
) -> dict:
    """The salsa clips as ``salsa`` and the ballet clips beside them, ``speed_clips`` also
    played at ``speeds``, ``pitch_clips`` also danced with the pelvis at ``pitches``,
    ``spin_clips`` also danced with spins at ``spins``."""
    return {
        "garment": CPU_SKIRT,
        # a leap's thigh goes up to 8.8 cm into the hips: a clip whose legs fold deeper
        # than 5 cm turns its limbs up to 30 degrees (10 ballet clips; no salsa clip,
        # whose legs fold 4.9 cm at most)
        "unfold": {"deep_degrees": 30.0},
        "motions": {
            "kind": "bvh",
            "folder": "{salsa}",
            "specs": tuple(f"{{ballet}}/{clip}.bvh" for clip in BALLET_CLIPS),
            "test": SALSA_TEST + BALLET_TEST,
            "start_frame": 10,
            "chain_test": True,
            "speeds": speeds,
            "speed_clips": speed_clips,
            "pitches": pitches,
            "pitch_clips": pitch_clips,
            "spins": spins,
            "spin_clips": spin_clips,
        },
    }


# Every preset, by name: a configuration file's fields (see the module's docstring).
PRESETS: dict[str, dict] = {
    "tiny": _TINY,
    "demo": {
        "garment": CPU_SKIRT,
        "cloth": {"settle_seconds": 0.6, "blend_seconds": 0.4},
        "motions": {"kind": "procedural", "count": 4, "seconds": 4.0, "test_every": 4},
    },
    "salsa": _salsa(()),
    "salsa-speed": _salsa((1.25,)),
    "salsa-speeds": _salsa((1.25, 1.5)),
    "dance": _dance(),
    "dance-speed": _dance(speeds=(1.25, 0.8), speed_clips=BALLET_TRAIN),
    "dance-pitch": _dance(pitches=(10.0, -10.0), pitch_clips=BALLET_TRAIN),
    "dance-spin": _dance(spins=(1.0,), spin_clips=BALLET_TRAIN),
    "dance-spins": _dance(spins=(1.0, 0.5), spin_clips=BALLET_TRAIN),
    "dance-spins-slow": _dance(spins=(1.0, 0.5, "1,ramp=0.8,hold=0"), spin_clips=BALLET_TRAIN),
    "dance-turns": _dance(
        spins=(1.0, 0.5, "1,ramp=0.8,hold=0", "2,ramp=0.25,hold=0"), spin_clips=BALLET_TRAIN
    ),
    "paper": {
        "garment": {"type": "skirt", "resolution": "paper", "style": "flared"},
        "cloth": {"device": "cuda:0"},
        "motions": {
            "kind": "bvh",
            "folder": "{salsa}",
            "test": SALSA_TEST,
            "count": 6,
            "seconds": 60.0,
            "start_frame": 10,
        },
    },
    "dress-tiny": {
        **_TINY,
        "garment": {
            "type": "dress",
            "style": "strapless",
            "rings": 10,
            "segments": 24,
            "length": 0.5,
        },
        "cloth": {**_TINY["cloth"], "arm_collision": "upper"},
    },
    "dress": {
        "garment": {"type": "dress", "resolution": "cpu", "style": "straps"},
        "cloth": {"settle_seconds": 0.6, "blend_seconds": 0.4, "arm_collision": "upper"},
        "motions": {"kind": "procedural", "count": 6, "seconds": 4.0, "test_every": 6},
    },
}


def default_salsa_folder() -> str:
    """``../shared/mocap/cmu-salsa`` beside the repository: the salsa clips' folder."""
    return str(Path(__file__).resolve().parents[3].parent / "shared/mocap/cmu-salsa")


def _with_folders(value, salsa: str, ballet: str):
    """``value`` with the ``{salsa}`` and ``{ballet}`` folders of its texts filled in."""
    if isinstance(value, dict):
        return {k: _with_folders(v, salsa, ballet) for k, v in value.items()}
    if isinstance(value, tuple):
        return tuple(_with_folders(v, salsa, ballet) for v in value)
    if isinstance(value, str):
        for mark, folder in (("{salsa}", salsa), ("{ballet}", ballet)):
            if value == mark:
                return folder
            if value.startswith(mark + "/"):
                return str(Path(folder) / value[len(mark) + 1 :])
    return value


def preset(name: str, bvh_folder: str | None = None) -> DatasetConfig:
    """The data set configuration of a preset of :data:`PRESETS` (a fresh one).

    Args:
        name: the preset.
        bvh_folder: the salsa clips' folder (default :func:`default_salsa_folder`); the
            ballet clips are in ``cmu-ballet`` beside it.

    Raises:
        LoosefitInputError: an unknown name.
    """
    if name not in PRESETS:
        raise LoosefitInputError("--preset", "preset", "one of " + ", ".join(PRESETS), repr(name))
    salsa = bvh_folder or default_salsa_folder()
    ballet = str(Path(salsa).parent / "cmu-ballet")
    table = _with_folders(copy.deepcopy(PRESETS[name]), salsa, ballet)
    return config_from_dict({**table, "preset": name}, f"preset {name}")
