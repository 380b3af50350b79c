"""Turns on the spot added to a motion: the same steps with pirouettes in them.

A loose skirt is most itself in a turn: it flares out and trails the body. A data set of
captured dances holds few turns, each from the poses its dancer happened to turn from, so a
model trained on it learns the turns it has seen rather than what turning does to the
cloth. :func:`spin_motion` turns the whole body about the vertical through the pelvis,
pirouette after pirouette, on top of whatever the capture does: every turn comes from
another pose of the dance.

A :class:`Spin` says how each spin turns: its rate rises smoothly (smoothstep) over
``ramp`` seconds to its peak of ``turns`` turns a second, holds for ``hold`` seconds and
falls back over ``ramp`` (:func:`spin_rates`). The first spin starts
:data:`SPIN_FIRST_SECONDS` into the clip, the next :data:`SPIN_REST_SECONDS` after each
ends, each turning the other way from the one before (the heading comes back near where it
was). The default, the spec ``spin:1:MOTION``, rises over 0.4 s and holds 0.8 s: 1.2 turns
round a spin. A dancer's turn builds more slowly and hardly holds (the ballet clip 05_02
rises over about 0.8 s to 6.2 rad/s and falls back at once): ``spin:1,ramp=0.8,hold=0:MOTION``.

The joints' local rotations and the root's path are kept: the body turns about its pelvis
as it travels (the feet slide on the floor, which the cloth does not see).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.geometry.rotations import axis_angle_to_matrix
from loosefit.types import Motion

# the default spin: its rate's rise and fall, and its hold at the peak (seconds)
SPIN_RAMP_SECONDS = 0.4
SPIN_HOLD_SECONDS = 0.8
# the first spin's start, and the quiet between one spin's end and the next one's start
SPIN_FIRST_SECONDS = 1.0
SPIN_REST_SECONDS = 1.4
# what a spec may ask for: a dancer's fastest spins (the salsa captures turn at up to 3.9
# turns a second, 25 rad/s), a rise from a flick to a slow wind-up, a hold of a few turns
MAX_TURNS_PER_SECOND = 4.0
MIN_RAMP_SECONDS, MAX_RAMP_SECONDS = 0.1, 2.0
MAX_HOLD_SECONDS = 10.0
# what every caller that takes a spin asks for, in its error
SPIN_FORM = (
    f"TURNS[,ramp=SECONDS][,hold=SECONDS]: turns a second other than 0, from "
    f"-{MAX_TURNS_PER_SECOND:g} to {MAX_TURNS_PER_SECOND:g}; a ramp from {MIN_RAMP_SECONDS:g} "
    f"to {MAX_RAMP_SECONDS:g} s (default {SPIN_RAMP_SECONDS:g}); a hold from 0 to "
    f"{MAX_HOLD_SECONDS:g} s (default {SPIN_HOLD_SECONDS:g})"
)


@dataclass(frozen=True)
class Spin:
    """How each spin turns the body (see the module's docstring).

    ``turns``: the peak rate in turns a second, its sign the first spin's direction
    (positive turns left, about +Z). ``ramp``: the seconds its rate takes to rise to the peak,
    and to fall back. ``hold``: the seconds it holds the peak.
    """

    turns: float
    ramp: float = SPIN_RAMP_SECONDS
    hold: float = SPIN_HOLD_SECONDS

    @property
    def seconds(self) -> float:
        """One spin's length: its rise, hold and fall."""
        return 2.0 * self.ramp + self.hold

    @property
    def every(self) -> float:
        """Seconds from one spin's start to the next one's."""
        return self.seconds + SPIN_REST_SECONDS

    def is_valid(self) -> bool:
        """Whether :func:`spin_motion` takes it: a finite rate other than 0 within
        :data:`MAX_TURNS_PER_SECOND`, a ramp and hold within their bounds."""
        t = self.turns
        return (
            math.isfinite(t)
            and t != 0
            and abs(t) <= MAX_TURNS_PER_SECOND
            and MIN_RAMP_SECONDS <= self.ramp <= MAX_RAMP_SECONDS
            and 0.0 <= self.hold <= MAX_HOLD_SECONDS
        )

    def spec(self) -> str:
        """The spec's field: ``TURNS``, with ``,ramp=`` and ``,hold=`` where not the default
        (``spin:`` + this + ``:MOTION`` spins a motion so)."""
        return f"{self.turns:g}" + "".join(f",{k}={v:g}" for k, v in self._changed())

    def label(self) -> str:
        """A name's part: ``TURNS``, with ``_rampS`` and ``_holdS`` where not the default (the
        data set's clip ``NAME_spin`` + this)."""
        return f"{self.turns:g}" + "".join(f"_{k}{v:g}" for k, v in self._changed())

    def _changed(self) -> list[tuple[str, float]]:
        pairs = [("ramp", self.ramp, SPIN_RAMP_SECONDS), ("hold", self.hold, SPIN_HOLD_SECONDS)]
        return [(k, v) for k, v, default in pairs if v != default]


def read_spin(value: float | str | Spin) -> Spin | None:
    """A :class:`Spin` from a rate (turns a second, the default ramp and hold), the spec's
    field ``TURNS[,ramp=SECONDS][,hold=SECONDS]`` or a :class:`Spin`; None for one that does
    not read or is beyond :data:`SPIN_FORM`'s bounds."""
    if isinstance(value, Spin):
        spin = value
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        spin = Spin(float(value))
    elif isinstance(value, str):
        head, *rest = value.split(",")
        fields: dict[str, float] = {}
        try:
            turns = float(head)
            for part in rest:
                key, eq, number = part.partition("=")
                key = key.strip()
                if not eq or key not in ("ramp", "hold") or key in fields:
                    return None
                fields[key] = float(number)
        except ValueError:
            return None
        spin = Spin(turns, **fields)
    else:
        return None
    return spin if spin.is_valid() else None


def _as_spin(spin: Spin | float) -> Spin:
    """A :class:`Spin` as given, or one of the default ramp and hold peaking at a bare rate."""
    return spin if isinstance(spin, Spin) else Spin(float(spin))


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _spin_starts(num_frames: int, fps: float, spin: Spin) -> list[float]:
    """Seconds: when each spin that fits whole in a clip of ``num_frames`` at ``fps`` starts
    (``SPIN_FIRST_SECONDS + k spin.every``, none that would end after the last frame)."""
    last = (num_frames - 1) / fps
    starts: list[float] = []
    while (start := SPIN_FIRST_SECONDS + len(starts) * spin.every) + spin.seconds <= last:
        starts.append(start)
    return starts


def spin_rates(num_frames: int, fps: float, spin: Spin | float) -> np.ndarray:
    """(T,) the yaw rate (rad/s, positive turns left) the spins add at each frame.

    Every spin that fits in the clip whole: spin ``k`` starts at ``SPIN_FIRST_SECONDS + k
    spin.every``, its rate rising over ``spin.ramp`` seconds to ``2 pi spin.turns`` (its sign:
    the first spin's direction), holding ``spin.hold`` and falling back over ``spin.ramp``;
    it turns the other way from spin ``k - 1``. None starts that would end after the last
    frame. A bare number is the rate of a :class:`Spin` of the default ramp and hold.
    """
    spin = _as_spin(spin)
    t = np.arange(num_frames, dtype=np.float64) / fps
    peak = 2.0 * math.pi * spin.turns
    rates = np.zeros(num_frames)
    for k, start in enumerate(_spin_starts(num_frames, fps, spin)):
        s = t - start
        envelope = _smoothstep(s / spin.ramp) * _smoothstep((spin.seconds - s) / spin.ramp)
        rates += (-1.0) ** k * peak * envelope
    return rates


def spin_count(num_frames: int, fps: float, spin: Spin | float = 1.0) -> int:
    """How many spins of ``spin``'s length a clip of ``num_frames`` at ``fps`` holds
    (:func:`spin_rates`)."""
    return len(_spin_starts(num_frames, fps, _as_spin(spin)))


def spin_motion(motion: Motion, spin: Spin | float) -> Motion:
    """The motion with spins on the spot added (see the module's docstring).

    Args:
        motion: T frames on a skeleton whose root is joint 0.
        spin: how each spin turns; a bare number is its peak rate in turns a second (the
            sign the first spin's direction, positive turns left, about +Z) with the
            default ramp and hold.

    Returns:
        A new :class:`Motion` of the same frames, joints, rate and root path, the root turned
        about the vertical by the spins' angle so far, named ``spin:SPEC:NAME``
        (:meth:`Spin.spec`), its ``meta["spins"]`` the number of spins added.

    Raises:
        LoosefitInputError: a rate that is zero, not finite or beyond the bound, a ramp or
            hold beyond theirs; a motion too short to hold one spin.
    """
    valid = read_spin(spin)
    if valid is None:
        raise LoosefitInputError(f"motion '{motion.name}'", "spin", SPIN_FORM, repr(spin))
    spin = valid
    count = spin_count(motion.num_frames, motion.fps, spin)
    if count == 0:
        need = math.floor((SPIN_FIRST_SECONDS + spin.seconds) * motion.fps)
        while spin_count(need, motion.fps, spin) == 0:
            need += 1
        raise LoosefitInputError(
            f"motion '{motion.name}'",
            "frames",
            f"at least {need} frames at {motion.fps:g} fps to hold a spin "
            f"({SPIN_FIRST_SECONDS:g} s in, {spin.seconds:g} s long)",
            motion.num_frames,
        )
    rates = spin_rates(motion.num_frames, motion.fps, spin)
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
        f"spin:{spin.spec()}:{motion.name}",
        meta,
    )
