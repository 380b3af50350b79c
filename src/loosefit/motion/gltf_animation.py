"""A glTF animation's keyframes, read, checked and sampled at the clip's frame rate.

:func:`animation_channels` reads an animation's channels on nodes (translation, rotation,
scale; morph weights are not read); :func:`sample_channel` evaluates one at given times
(``LINEAR`` with slerp for rotations, ``STEP``, ``CUBICSPLINE``); the frames run from the
first keyframe to the last at the keyframes' rate or :data:`DEFAULT_FPS` (see
:mod:`loosefit.motion.gltf` for the rule).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from loosefit.geometry.rotations import _slerp_f64
from loosefit.motion.gltf_file import (
    GltfDocument,
    doc_index,
    doc_item,
    doc_list,
    gltf_error,
    read_accessor,
)

DEFAULT_FPS = 30.0  # sampling rate when the keyframes are too sparse to give one
MIN_KEY_FPS = 10.0  # keyframes at least this dense set the sampling rate
MAX_SECONDS = 3600.0  # the longest animation read (an hour, as dance:SECONDS takes)
INTERPOLATIONS = ("LINEAR", "STEP", "CUBICSPLINE")
_PATHS = {"translation": 3, "rotation": 4, "scale": 3}  # the channels read; weights are not


def sample_channel(
    times: np.ndarray, values: np.ndarray, interpolation: str, at: np.ndarray, rotation: bool
) -> np.ndarray:
    """A glTF animation sampler evaluated at given times.

    Args:
        times: (K,) non-decreasing keyframe times, seconds.
        values: (K, W) keyframe values, or (3K, W) for ``CUBICSPLINE`` (in-tangent,
            value, out-tangent per key); rotations are quaternions ``(x, y, z, w)``.
        interpolation: ``LINEAR``, ``STEP`` or ``CUBICSPLINE``.
        at: (T,) times to sample.
        rotation: the values are quaternions (slerp for ``LINEAR``, normalised).

    Returns:
        (T, W) float64 values; the first and last keys hold outside the keyframes.
    """
    times = np.asarray(times, np.float64)
    values = np.asarray(values, np.float64)
    K = len(times)
    if interpolation == "CUBICSPLINE":
        tangents_in, values, tangents_out = values[0::3], values[1::3], values[2::3]
    if K == 1:
        out = np.repeat(values[:1], len(at), axis=0)
    elif interpolation == "STEP":
        out = values[np.clip(np.searchsorted(times, at, side="right") - 1, 0, K - 1)]
    else:
        k = np.clip(np.searchsorted(times, at, side="right") - 1, 0, K - 2)  # (T,) segment
        dt = times[k + 1] - times[k]
        s = np.clip((at - times[k]) / np.where(dt > 0, dt, 1.0), 0.0, 1.0)
        s = np.where(dt > 0, s, (at >= times[k + 1]).astype(np.float64))[:, None]  # (T, 1)
        v0, v1 = values[k], values[k + 1]
        if interpolation == "CUBICSPLINE":  # Hermite, glTF 2.0 appendix C
            s2, s3 = s * s, s * s * s
            d = dt[:, None]
            out = (
                (2 * s3 - 3 * s2 + 1) * v0
                + (s3 - 2 * s2 + s) * d * tangents_out[k]
                + (-2 * s3 + 3 * s2) * v1
                + (s3 - s2) * d * tangents_in[k + 1]
            )
        elif rotation:
            wxyz = _slerp_f64(np.roll(v0, 1, -1), np.roll(v1, 1, -1), s[:, 0])
            out = np.roll(wxyz, -1, -1)
        else:
            out = (1 - s) * v0 + s * v1
    if rotation:
        norm = np.linalg.norm(out, axis=-1, keepdims=True)
        out = np.where(norm > 1e-12, out / np.where(norm > 1e-12, norm, 1.0), [0, 0, 0, 1.0])
    return out


# A channel: (K,) keyframe times, (K, W) or (3K, W) values, the interpolation.
Channel = tuple[np.ndarray, np.ndarray, str]


def animation_channels(
    doc: GltfDocument, animation: str | int | None, num_nodes: int
) -> tuple[int, dict, dict[tuple[int, str], Channel]]:
    """The animation named or numbered ``animation`` (default: the first): its index, its
    JSON and its channels on nodes.

    Raises:
        LoosefitInputError: a file with no animation, or none of that name or number.
    """
    if not doc_list(doc, "animations"):
        raise gltf_error(
            doc,
            "animations",
            "an animation",
            "none in the file",
            hint="export with animation on (Blender: glTF export > Animation)",
        )
    a = doc_index(doc, "animations", animation, 0, "animation")
    anim = doc_item(doc, "animations", a, f"animations[{a}]")
    return a, anim, _read_channels(doc, anim, a, num_nodes)


def _read_channels(
    doc: GltfDocument, anim: dict, a: int, num_nodes: int
) -> dict[tuple[int, str], Channel]:
    """(node, path) -> its sampler's keyframes, for the animation's channels on nodes."""
    channels: dict[tuple[int, str], Channel] = {}
    samplers = anim.get("samplers", [])
    for c, ch in enumerate(anim.get("channels", [])):
        where = f"animations[{a}].channels[{c}]"
        target = ch.get("target", {}) if isinstance(ch, dict) else {}
        node, prop = target.get("node"), target.get("path")
        if prop not in _PATHS or node is None:
            continue  # morph weights, or an extension's pointer
        if not (isinstance(node, int) and 0 <= node < num_nodes):
            raise gltf_error(doc, f"{where}.target.node", f"a node index below {num_nodes}", node)
        s = ch.get("sampler")
        if not (isinstance(s, int) and 0 <= s < len(samplers)):
            raise gltf_error(doc, f"{where}.sampler", f"a sampler index below {len(samplers)}", s)
        channels[(node, prop)] = _read_sampler(
            doc, samplers[s], f"animations[{a}].samplers[{s}]", prop
        )
    return channels


def _read_sampler(doc: GltfDocument, sampler: dict, swhere: str, prop: str) -> Channel:
    """A sampler's keyframe times, values and interpolation, checked for channel ``prop``."""
    interp = sampler.get("interpolation", "LINEAR")
    if interp not in INTERPOLATIONS:
        raise gltf_error(doc, f"{swhere}.interpolation", f"one of {INTERPOLATIONS}", repr(interp))
    times = read_accessor(doc, sampler.get("input"), f"{swhere}.input")[:, 0]
    values = read_accessor(doc, sampler.get("output"), f"{swhere}.output")
    if np.any(np.diff(times) < 0):
        raise gltf_error(
            doc,
            f"{swhere}.input",
            "increasing keyframe times",
            f"a time going back at key {int(np.argmax(np.diff(times) < 0)) + 1}",
        )
    keys = len(times) * (3 if interp == "CUBICSPLINE" else 1)
    if values.shape != (keys, _PATHS[prop]):
        raise gltf_error(
            doc,
            f"{swhere}.output",
            f"{keys} values of {_PATHS[prop]} components ({prop}, {interp})",
            f"{values.shape[0]} of {values.shape[1]}",
        )
    return times, values, interp


@dataclass(frozen=True)
class FrameTimes:
    """When the clip's frames are sampled.

    Attributes:
        t0, t1: the first and last keyframe times, seconds.
        fps: the sampling rate; ``how``: how it was chosen.
        at: (T,) the frames' times, seconds.
    """

    t0: float
    t1: float
    fps: float
    how: str
    at: np.ndarray


def frame_times(doc: GltfDocument, a: int, channels: dict, fps: float | None) -> FrameTimes:
    """The frames' times, from the first keyframe to the last at the sampling rate."""
    t0 = min(t[0] for t, _, _ in channels.values())
    t1 = max(t[-1] for t, _, _ in channels.values())
    fps, fps_how = _frame_rate(doc, channels, fps)
    if t1 - t0 > MAX_SECONDS:
        raise gltf_error(
            doc,
            f"animations[{a}].samplers",
            f"keyframes over at most {MAX_SECONDS:g} s",
            f"{t0:g} s to {t1:g} s",
        )
    # keyframe times are float32 in a file: a last key at 101/30 s reads 100.99999 frames
    T = int(np.floor((t1 - t0) * fps + 1e-3)) + 1
    at = t0 + np.arange(T) / fps  # (T,)
    return FrameTimes(t0, t1, fps, fps_how, at)


def _frame_rate(doc: GltfDocument, channels: dict, fps: float | None) -> tuple[float, str]:
    """The sampling rate and how it was chosen."""
    if fps is not None:
        if not (np.isfinite(fps) and fps > 0):
            raise gltf_error(doc, "fps", "a positive frame rate", repr(fps))
        return float(fps), "as asked"
    spacings = [
        np.median(np.diff(t)[np.diff(t) > 0])
        for t, _, _ in channels.values()
        if np.any(np.diff(t) > 0)
    ]
    if not spacings:
        return DEFAULT_FPS, "a single key: the default"
    rate = 1.0 / min(spacings)
    if rate < MIN_KEY_FPS:
        return DEFAULT_FPS, f"keyframes {rate:.3g} per second are sparse: the default"
    if abs(rate - round(rate)) < 0.005 * rate:
        rate = float(round(rate))
    return float(rate), "the keyframes' rate"
