"""Turns on the spot added to a motion: the same steps with pirouettes in them.

A loose skirt is most itself in a turn: it flares out and trails the body. A data set of
captured dances holds few turns, each from the poses its dancer happened to turn from, so a
model trained on it learns the turns it has seen rather than what turning does to the
cloth. :func:`spin_motion` turns the whole body about the vertical through the pelvis,
pirouette after pirouette, on top of whatever the capture does: every turn comes from
another pose of the dance.

Each spin's rate rises smoothly to its peak, holds and falls back (:func:`spin_rates`):
:data:`SPIN_SECONDS` long, ramps of :data:`SPIN_RAMP_SECONDS`, one starting every
:data:`SPIN_EVERY_SECONDS` from :data:`SPIN_FIRST_SECONDS` into the clip, each turning the
other way from the one before (the heading comes back near where it was). At one turn a
second (the spec ``spin:1:MOTION``) each spin turns the body 1.2 times round.

The joints' local rotations and the root's path are kept: the body turns about its pelvis
as it travels (the feet slide on the floor, which the cloth does not see).
"""

from __future__ import annotations

import math

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.geometry.rotations import axis_angle_to_matrix
from loosefit.types import Motion

# a spin's length, its rate's rise and fall, the time between spin starts and the first start
SPIN_SECONDS = 1.6
SPIN_RAMP_SECONDS = 0.4
SPIN_EVERY_SECONDS = 3.0
SPIN_FIRST_SECONDS = 1.0
# what a spec may ask for: a dancer's fastest spins (the salsa captures turn at up to 3.9
# turns a second, 25 rad/s)
MAX_TURNS_PER_SECOND = 4.0
# what every caller that takes a spin rate asks for, in its error
SPIN_RATES = (
    f"turns a second other than 0, from -{MAX_TURNS_PER_SECOND:g} to {MAX_TURNS_PER_SECOND:g}"
)


def is_spin_rate(turns_per_second: float) -> bool:
    """Whether a spin rate is one :func:`spin_motion` takes: finite, not 0, within
    :data:`MAX_TURNS_PER_SECOND` either way."""
    t = turns_per_second
    return math.isfinite(t) and t != 0 and abs(t) <= MAX_TURNS_PER_SECOND


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _spin_starts(num_frames: int, fps: float) -> list[float]:
    """Seconds: when each spin that fits whole in a clip of ``num_frames`` at ``fps`` starts
    (``SPIN_FIRST_SECONDS + k SPIN_EVERY_SECONDS``, none that would end after the last
    frame)."""
    last = (num_frames - 1) / fps
    starts: list[float] = []
    while (start := SPIN_FIRST_SECONDS + len(starts) * SPIN_EVERY_SECONDS) + SPIN_SECONDS <= last:
        starts.append(start)
    return starts


def spin_rates(num_frames: int, fps: float, turns_per_second: float) -> np.ndarray:
    """(T,) the yaw rate (rad/s, positive turns left) the spins add at each frame.

    Every spin that fits in the clip whole: spin ``k`` starts at ``SPIN_FIRST_SECONDS + k
    SPIN_EVERY_SECONDS``, peaks at ``2 pi turns_per_second`` (its sign: the first spin's
    direction) and turns the other way from spin ``k - 1``; none starts that would end
    after the last frame.
    """
    t = np.arange(num_frames, dtype=np.float64) / fps
    peak = 2.0 * math.pi * turns_per_second
    rates = np.zeros(num_frames)
    for k, start in enumerate(_spin_starts(num_frames, fps)):
        s = t - start
        envelope = _smoothstep(s / SPIN_RAMP_SECONDS) * _smoothstep(
            (SPIN_SECONDS - s) / SPIN_RAMP_SECONDS
        )
        rates += (-1.0) ** k * peak * envelope
    return rates


def spin_count(num_frames: int, fps: float) -> int:
    """How many spins a clip of ``num_frames`` at ``fps`` holds (:func:`spin_rates`)."""
    return len(_spin_starts(num_frames, fps))


def spin_motion(motion: Motion, turns_per_second: float) -> Motion:
    """The motion with spins on the spot added (see the module's docstring).

    Args:
        motion: T frames on a skeleton whose root is joint 0.
        turns_per_second: each spin's peak rate; its sign the first spin's direction
            (positive turns left, about +Z); at most :data:`MAX_TURNS_PER_SECOND` either way.

    Returns:
        A new :class:`Motion` of the same frames, joints, rate and root path, the root turned
        about the vertical by the spins' angle so far, named ``spin:TURNS:NAME``, its
        ``meta["spins"]`` the number of spins added.

    Raises:
        LoosefitInputError: a rate that is zero, not finite or beyond the bound; a motion too
            short to hold one spin.
    """
    tps = turns_per_second
    if not is_spin_rate(tps):
        raise LoosefitInputError(f"motion '{motion.name}'", "spin rate", SPIN_RATES, repr(tps))
    count = spin_count(motion.num_frames, motion.fps)
    if count == 0:
        need = math.floor((SPIN_FIRST_SECONDS + SPIN_SECONDS) * motion.fps)
        while spin_count(need, motion.fps) == 0:
            need += 1
        raise LoosefitInputError(
            f"motion '{motion.name}'",
            "frames",
            f"at least {need} frames at {motion.fps:g} fps to hold a spin "
            f"({SPIN_FIRST_SECONDS:g} s in, {SPIN_SECONDS:g} s long)",
            motion.num_frames,
        )
    rates = spin_rates(motion.num_frames, motion.fps, tps)
    # the angle turned by frame t: the rates summed over the frames before it (trapezoids)
    steps = 0.5 * (rates[1:] + rates[:-1]) / motion.fps
    angle = np.concatenate([[0.0], np.cumsum(steps)])  # (T,)
    axis = np.zeros((motion.num_frames, 3))
    axis[:, 2] = angle
    turn = axis_angle_to_matrix(axis).astype(np.float64)  # (T, 3, 3)
    out = motion.rotations.astype(np.float64).copy()
    out[:, 0] = turn @ out[:, 0]
    meta = {**motion.meta, "spins": int(motion.meta.get("spins", 0)) + count}
    return Motion(
        motion.joint_names,
        out.astype(np.float32),
        motion.root_translation,
        motion.fps,
        f"spin:{tps:g}:{motion.name}",
        meta,
    )
