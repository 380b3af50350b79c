"""One entry point for every way a user names a motion.

A motion capture file (BVH, glTF/GLB, an SMPL pose .npz), a saved motion, or a
procedural move.
"""

from __future__ import annotations

import math
from pathlib import Path

from loosefit.body.avatar import Avatar
from loosefit.errors import LoosefitInputError
from loosefit.motion.bvh import BVH_UNITS
from loosefit.motion.chain import chain_motions
from loosefit.motion.files import CLIP_READERS, is_capture_file, read_clip
from loosefit.motion.mirror import mirror_motion
from loosefit.motion.pelvis import MAX_PITCH_DEGREES, pitch_pelvis
from loosefit.motion.procedural import MOVES, named_motion, random_dance
from loosefit.motion.resample import resample_motion, retime_motion
from loosefit.motion.retarget import RetargetConfig, retarget_bvh
from loosefit.motion.smpl import npz_fields
from loosefit.motion.spin import SPIN_FORM, read_spin, spin_motion
from loosefit.types import Motion

PROCEDURAL_NAMES = ("dance", *MOVES)


# what a spec may ask for: an hour of dance; from ten times slower to ten times faster
MAX_DANCE_SECONDS = 3600.0
MIN_SPEED, MAX_SPEED = 0.1, 10.0


# Motion specs that set one RetargetConfig field for the motion after them:
# prefix -> (the field, the spec's form, what it takes)
_SETTING_PREFIXES = {
    "joint-map:": (
        "joint_map",
        "joint-map:MAP:MOTION",
        "auto, a joint map's name or a map file, and a motion",
    ),
    "animation:": (
        "animation",
        "animation:NAME:MOTION",
        "a glTF animation's name or index, and a motion",
    ),
}


def load_motion(
    spec: str | Path,
    avatar: Avatar,
    fps: float = 30.0,
    seed: int = 0,
    retarget: RetargetConfig | None = None,
    max_frames: int | None = None,
    *,
    start_frame: int = 0,
) -> Motion:
    """A motion on the avatar's skeleton from a file or a procedural name.

    Args:
        spec: a motion capture file, retargeted: ``.bvh``, ``.gltf``/``.glb`` (a skin
            and an animation, :mod:`~loosefit.motion.gltf`) or an SMPL-family ``.npz``
            (``poses``, ``trans``, a frame rate; :mod:`~loosefit.motion.smpl`); a ``.npz``
            motion saved by :meth:`Motion.save` (told from an SMPL one by its fields);
            a procedural move name (``spin``, ``walk``, ...),
            ``dance`` (a random dance of 12 s), ``dance:SECONDS``; any of these
            behind ``mirror:``, danced left-right mirrored
            (:func:`~loosefit.motion.mirror.mirror_motion`), or behind
            ``speed:FACTOR:``, played FACTOR times as fast at the same frame rate
            (:func:`~loosefit.motion.resample.retime_motion`), or behind
            ``pitch:DEGREES:``, the pelvis pitched DEGREES more (positive raises its
            front), the spine and legs as captured
            (:func:`~loosefit.motion.pelvis.pitch_pelvis`), or behind
            ``spin:TURNS:``, with spins on the spot added, each peaking at TURNS turns a
            second, alternately left and right, or ``spin:TURNS,ramp=S,hold=S:``, each
            rising over ``ramp`` seconds and holding ``hold`` (default 0.4 and 0.8; either
            may be left out) (:func:`~loosefit.motion.spin.spin_motion`), or behind
            ``frames:START:STOP:``, its frames START to STOP - 1 (at ``fps``, before
            ``start_frame`` and ``max_frames``); a BVH file behind ``units:UNIT:``
            (m, cm, mm) or ``scale:METRES_PER_UNIT:``, read in that unit (otherwise
            guessed; a dancer outside 1.2-2.2 m is refused, and so is a capture whose
            poses fail :func:`~loosefit.motion.pose_check.check_pose`); a BVH file behind
            ``joint-map:MAP:`` (``auto``, ``daz``, ``cmu_mb`` or a ``.yaml``/``.toml``
            map file; see :func:`~loosefit.motion.retarget.resolve_joint_map`), its joints
            mapped so; a glTF file behind ``animation:NAME:`` (a name or an index), that
            animation; or several of these
            joined by ``+``: played one after another as one motion
            (:func:`~loosefit.motion.chain.chain_motions`, 0.5 s transitions).
        avatar: the avatar that the motion must fit.
        fps: the frame rate of the result.
        seed: seeds procedural motions.
        retarget: how motion capture files are read and mapped (BVH, glTF, SMPL).
        max_frames: keep at most this many frames.
        start_frame: drop the frames before this one (after resampling to ``fps``);
            in a chain, from each of its parts.

    Returns:
        A validated :class:`Motion` on ``avatar``'s joints at ``fps``.
    """
    text = str(spec)
    path = Path(text)
    if "+" in text and not path.exists():
        parts = [p for p in text.split("+") if p]
        motion = chain_motions(
            [
                load_motion(p, avatar, fps, seed + i, retarget, None, start_frame=start_frame)
                for i, p in enumerate(parts)
            ]
        )
        return motion if max_frames is None else motion.slice(0, max_frames)
    motion = _load_one(text, avatar, fps, seed, retarget)
    return _trim(motion, start_frame, max_frames)


def _load_one(
    text: str, avatar: Avatar, fps: float, seed: int, retarget: RetargetConfig | None
) -> Motion:
    """One motion spec (no ``+`` chain), every frame of it: by its prefix or its file."""
    path = Path(text)
    setting = next((k for k in _SETTING_PREFIXES if text.startswith(k)), None)
    if setting is not None and not path.exists():
        return _load_with_setting(text, setting, avatar, fps, seed, retarget)
    if text.startswith(("units:", "scale:")) and not path.exists():
        return _load_in_units(text, avatar, fps, seed, retarget)
    if text.startswith("mirror:") and not path.exists():
        return mirror_motion(load_motion(text[len("mirror:") :], avatar, fps, seed, retarget))
    if text.startswith("speed:") and not path.exists():
        return _load_retimed(text, avatar, fps, seed, retarget)
    if text.startswith("pitch:") and not path.exists():
        return _load_pitched(text, avatar, fps, seed, retarget)
    if text.startswith("spin:") and not path.exists():
        return _load_spun(text, avatar, fps, seed, retarget)
    if text.startswith("frames:") and not path.exists():
        return _load_frames(text, avatar, fps, seed, retarget)
    if path.suffix.lower() in CLIP_READERS and (
        path.suffix.lower() != ".npz" or is_capture_file(path)
    ):
        cfg = retarget or RetargetConfig()
        cfg = RetargetConfig(**{**cfg.__dict__, "fps": fps})
        clip = read_clip(path, cfg)
        return retarget_bvh(clip, avatar.skeleton, avatar.floor_height, cfg)
    if path.suffix.lower() == ".npz":
        return _load_saved(path, avatar, fps)
    if text.split(":")[0] in PROCEDURAL_NAMES:
        return _procedural(text, avatar, fps, seed)
    raise LoosefitInputError(
        "motion",
        "spec",
        f"a .bvh, .gltf, .glb or .npz file, or one of {list(PROCEDURAL_NAMES)} "
        + "(dance:SECONDS)",
        repr(text),
    )


def _load_with_setting(
    text: str, setting: str, avatar: Avatar, fps: float, seed: int, retarget: RetargetConfig | None
) -> Motion:
    """``joint-map:MAP:MOTION`` or ``animation:NAME:MOTION``: one RetargetConfig field set."""
    field_name, form, wanted = _SETTING_PREFIXES[setting]
    value, _, inner = text[len(setting) :].partition(":")
    if not (value and inner):
        raise LoosefitInputError("motion", form, wanted, repr(text))
    cfg = RetargetConfig(**{**(retarget or RetargetConfig()).__dict__, field_name: value})
    return load_motion(inner, avatar, fps, seed, cfg)


def _load_in_units(
    text: str, avatar: Avatar, fps: float, seed: int, retarget: RetargetConfig | None
) -> Motion:
    """``units:UNIT:MOTION`` or ``scale:METRES_PER_UNIT:MOTION``."""
    key, _, rest = text.partition(":")
    value, _, inner = rest.partition(":")
    cfg = retarget or RetargetConfig()
    if key == "units":
        ok = value in BVH_UNITS
        cfg = RetargetConfig(**{**cfg.__dict__, "units": value, "scale": None})
    else:
        try:
            factor = float(value)
        except ValueError:
            factor = float("nan")
        ok = math.isfinite(factor) and factor > 0
        cfg = RetargetConfig(**{**cfg.__dict__, "scale": factor})
    if not (ok and inner):
        raise LoosefitInputError(
            "motion",
            f"{key}:{'UNIT' if key == 'units' else 'METRES_PER_UNIT'}:MOTION",
            "m, cm, mm or auto, and a motion"
            if key == "units"
            else "a positive factor and a motion",
            repr(text),
        )
    return load_motion(inner, avatar, fps, seed, cfg)


def _number_and_motion(text: str, prefix: str) -> tuple[float, str]:
    """``PREFIX:NUMBER:MOTION`` -> (NUMBER, MOTION); NaN for a number that does not read."""
    value, _, inner = text[len(prefix) :].partition(":")
    try:
        return float(value), inner
    except ValueError:
        return float("nan"), inner


def _load_retimed(
    text: str, avatar: Avatar, fps: float, seed: int, retarget: RetargetConfig | None
) -> Motion:
    """``speed:FACTOR:MOTION``: played FACTOR times as fast, at the same frame rate."""
    speed, inner = _number_and_motion(text, "speed:")
    if not (inner and MIN_SPEED <= speed <= MAX_SPEED):
        raise LoosefitInputError(
            "motion",
            "speed:FACTOR:MOTION",
            f"a factor from {MIN_SPEED:g} to {MAX_SPEED:g} and a motion",
            repr(text),
        )
    return retime_motion(load_motion(inner, avatar, fps, seed, retarget), speed)


def _load_pitched(
    text: str, avatar: Avatar, fps: float, seed: int, retarget: RetargetConfig | None
) -> Motion:
    """``pitch:DEGREES:MOTION``: the pelvis pitched DEGREES more, its children as captured."""
    degrees, inner = _number_and_motion(text, "pitch:")
    if not (inner and math.isfinite(degrees) and abs(degrees) <= MAX_PITCH_DEGREES):
        raise LoosefitInputError(
            "motion",
            "pitch:DEGREES:MOTION",
            f"degrees from -{MAX_PITCH_DEGREES:g} to {MAX_PITCH_DEGREES:g} and a motion",
            repr(text),
        )
    motion = load_motion(inner, avatar, fps, seed, retarget)
    return pitch_pelvis(motion, avatar.skeleton.parents, degrees)


def _load_spun(
    text: str, avatar: Avatar, fps: float, seed: int, retarget: RetargetConfig | None
) -> Motion:
    """``spin:TURNS[,ramp=SECONDS][,hold=SECONDS]:MOTION``: spins on the spot added, each
    peaking at TURNS turns a second (:class:`~loosefit.motion.spin.Spin`)."""
    field, _, inner = text[len("spin:") :].partition(":")
    spin = read_spin(field)
    if not (inner and spin is not None):
        raise LoosefitInputError(
            "motion", "spin:TURNS:MOTION", f"{SPIN_FORM}, and a motion", repr(text)
        )
    return spin_motion(load_motion(inner, avatar, fps, seed, retarget), spin)


def _load_frames(
    text: str, avatar: Avatar, fps: float, seed: int, retarget: RetargetConfig | None
) -> Motion:
    """``frames:START:STOP:MOTION``: its frames START to STOP - 1."""
    start, _, rest = text[len("frames:") :].partition(":")
    stop, _, inner = rest.partition(":")
    try:
        first, last = int(start), int(stop)
    except ValueError:
        first = last = -1
    if not (inner and 0 <= first < last):
        raise LoosefitInputError(
            "motion", "frames:START:STOP:MOTION", "0 <= START < STOP and a motion", repr(text)
        )
    motion = load_motion(inner, avatar, fps, seed, retarget)
    if last > motion.num_frames:
        raise LoosefitInputError(
            f"motion '{motion.name}'",
            "frames:START:STOP",
            f"STOP <= {motion.num_frames} (its frames)",
            last,
        )
    return motion.slice(first, last)


def _load_saved(path: Path, avatar: Avatar, fps: float) -> Motion:
    """A motion saved by :meth:`Motion.save`, checked on ``avatar``, resampled to ``fps``."""
    fields = npz_fields(path) if path.is_file() else ["rotations"]  # Motion.load says
    if "rotations" not in fields:
        raise LoosefitInputError(
            path,
            "rotations",
            "a loosefit motion (joint_names, rotations, root_translation, fps) or an SMPL "
            "pose file (poses, trans, mocap_framerate)",
            f"fields {sorted(fields)}",
        )
    motion = Motion.load(path)
    avatar.check_motion(motion)
    if abs(motion.fps - fps) > 1e-6:
        motion = resample_motion(motion, fps)
    return motion


def _procedural(text: str, avatar: Avatar, fps: float, seed: int) -> Motion:
    """A procedural move (``spin``, ``walk``, ...), ``dance`` or ``dance:SECONDS``."""
    name, _, arg = text.partition(":")
    if name == "dance" and arg:
        try:
            seconds = float(arg)
        except ValueError:
            seconds = float("nan")
        if not 0 < seconds <= MAX_DANCE_SECONDS:
            raise LoosefitInputError(
                "motion", "dance:SECONDS", f"seconds in (0, {MAX_DANCE_SECONDS:g}]", repr(arg)
            )
        return random_dance(avatar.joint_names, avatar.floor_height, seconds, seed, fps)
    return named_motion(name, avatar.joint_names, avatar.floor_height, seed, fps)


def _trim(motion: Motion, start_frame: int, max_frames: int | None) -> Motion:
    """Frames ``start_frame`` on, at most ``max_frames`` of them."""
    if not 0 <= start_frame < motion.num_frames:
        raise LoosefitInputError(
            f"motion '{motion.name}'", "start_frame", f"in [0, {motion.num_frames})", start_frame
        )
    stop = None if max_frames is None else start_frame + max_frames
    if start_frame or (stop is not None and stop < motion.num_frames):
        motion = motion.slice(start_frame, stop)
    return motion
