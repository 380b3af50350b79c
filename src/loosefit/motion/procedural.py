"""Procedural dance motions for the built-in data: walk, turn, spin, twirl, sway, kick, jump,
bow.

Each move is a function of time that returns, per frame, joint angles (axis-angle
vectors in the rest pose's world-aligned axes, which is what the avatar's local
rotations are) and the root's motion in the dancer's heading frame (speed
forward and sideways, turning rate, height). A dance is a list of moves with
durations; consecutive moves are cross-faded so the body never jumps, and the
root trajectory is integrated from the blended speeds, so turns and spins carry
the dancer around naturally.

Angle conventions on the avatar (Z up, facing -Y, left is +X): a negative
rotation about X swings a leg or arm forward, a positive one bends a knee back
or the spine forward; rotation about Z turns the body to its left.

Speeds are a dancer's: a spin reaches 1-2 turns a second (6-12 rad/s), enough
to flare a skirt; a kick lifts the leg 60-90 degrees in a quarter second.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.geometry.rotations import axis_angle_to_matrix
from loosefit.types import Motion

# Lowering of the arms from anny's A-pose (48 degrees below horizontal) to hang relaxed.
RELAXED_ARM = 0.5

# Joint angles: joint name -> (T, 3) axis-angle. Root motion: a dict of (T,) arrays.
Angles = dict[str, np.ndarray]


@dataclass
class MoveOutput:
    """What one move produces over its frames.

    Attributes:
        angles: joint name -> (T, 3) axis-angle local rotation (radians).
        forward: (T,) speed along the heading, m/s.
        sideways: (T,) speed to the dancer's left, m/s.
        turn_rate: (T,) yaw rate about +Z, rad/s (positive turns left).
        height: (T,) root height offset from standing, m.
    """

    angles: Angles
    forward: np.ndarray
    sideways: np.ndarray
    turn_rate: np.ndarray
    height: np.ndarray


def _zeros(t: np.ndarray) -> np.ndarray:
    return np.zeros_like(t)


def _vec(x=0.0, y=0.0, z=0.0, n: int = 1) -> np.ndarray:
    """(n, 3) axis-angle vectors from per-axis scalars or (n,) arrays."""
    out = np.zeros((n, 3))
    out[:, 0], out[:, 1], out[:, 2] = x, y, z
    return out


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def _envelope(t: np.ndarray, duration: float, ramp: float) -> np.ndarray:
    """0 -> 1 -> 0 over the move, with smooth ramps of ``ramp`` seconds."""
    ramp = max(min(ramp, duration / 2), 1e-6)
    return _smoothstep(t / ramp) * _smoothstep((duration - t) / ramp)


def _output(t, angles, forward=None, sideways=None, turn_rate=None, height=None) -> MoveOutput:
    return MoveOutput(
        angles=angles,
        forward=_zeros(t) if forward is None else forward,
        sideways=_zeros(t) if sideways is None else sideways,
        turn_rate=_zeros(t) if turn_rate is None else turn_rate,
        height=_zeros(t) if height is None else height,
    )


def _gait(t: np.ndarray, cadence: float, stride: float, arm_swing: float, bounce: float) -> Angles:
    """Leg, arm, pelvis and spine angles of a walking step cycle at ``cadence`` steps/s."""
    n = len(t)
    phase = np.pi * cadence * t  # one full cycle every two steps
    s, c = np.sin(phase), np.cos(phase)
    hip = stride * s
    a: Angles = {
        "LeftUpLeg": _vec(x=-hip, n=n),
        "RightUpLeg": _vec(x=hip, n=n),
        # The knee bends in the swing phase of each leg.
        "LeftLeg": _vec(x=0.9 * stride * np.clip(-c, 0, None) + 0.1, n=n),
        "RightLeg": _vec(x=0.9 * stride * np.clip(c, 0, None) + 0.1, n=n),
        "LeftFoot": _vec(x=0.3 * hip, n=n),
        "RightFoot": _vec(x=-0.3 * hip, n=n),
        # Arms relaxed down from the A-pose (about Y) and swinging against the legs.
        "LeftArm": _vec(x=arm_swing * s, y=RELAXED_ARM, n=n),
        "RightArm": _vec(x=-arm_swing * s, y=-RELAXED_ARM, n=n),
        "LeftForeArm": _vec(x=-0.2 - 0.2 * arm_swing * np.clip(-s, 0, None), n=n),
        "RightForeArm": _vec(x=-0.2 - 0.2 * arm_swing * np.clip(s, 0, None), n=n),
        "Hips": _vec(z=0.25 * stride * s, y=0.05 * bounce * c, n=n),
        "Spine": _vec(z=-0.3 * stride * s, n=n),
    }
    return a


def walk(t, duration, rng, speed=None, cadence=None, turn=0.0) -> MoveOutput:
    """Walking forward, optionally curving (``turn`` rad over the move)."""
    speed = rng.uniform(0.7, 1.4) if speed is None else speed
    cadence = rng.uniform(1.6, 2.2) if cadence is None else cadence
    stride = 0.28 * speed
    a = _gait(t, cadence, stride, arm_swing=0.35 * speed, bounce=1.0)
    height = -0.015 * np.abs(np.cos(np.pi * cadence * t))
    return _output(
        t,
        a,
        forward=np.full_like(t, speed),
        turn_rate=np.full_like(t, turn / duration),
        height=height,
    )


def turn(t, duration, rng, angle=None) -> MoveOutput:
    """Stepping round on the spot by ``angle`` radians (sign gives the direction)."""
    angle = rng.choice([-1, 1]) * rng.uniform(np.pi / 2, np.pi) if angle is None else angle
    a = _gait(t, 2.0, 0.15, arm_swing=0.15, bounce=0.5)
    a["Spine1"] = _vec(z=0.2 * np.sign(angle) * _envelope(t, duration, 0.3), n=len(t))
    rate = angle / duration * 2 * _envelope(t, duration, duration / 2)
    return _output(t, a, turn_rate=rate)


def spin(t, duration, rng, turns_per_s=None, arms="out") -> MoveOutput:
    """A pirouette-like spin on the spot, ramping up to ``turns_per_s`` and back down."""
    tps = rng.uniform(1.0, 2.0) if turns_per_s is None else turns_per_s
    direction = rng.choice([-1, 1])
    env = _envelope(t, duration, min(0.6, duration / 3))
    n = len(t)
    raise_ = {"out": 0.75, "up": 1.9, "in": 0.2}[arms]
    a: Angles = {
        # Arms lifted sideways (about Y: negative lifts the left arm, positive the right).
        "LeftArm": _vec(y=-raise_ * env, n=n),
        "RightArm": _vec(y=raise_ * env, n=n),
        "LeftForeArm": _vec(x=-0.3 * env, n=n),
        "RightForeArm": _vec(x=-0.3 * env, n=n),
        # Working leg drawn up (passe) at the spin's height.
        "LeftUpLeg": _vec(x=-0.6 * env, z=0.3 * env, n=n),
        "LeftLeg": _vec(x=1.4 * env, n=n),
        "Spine1": _vec(x=-0.05 * env, n=n),
    }
    height = 0.03 * env  # up on the ball of the foot
    return _output(t, a, turn_rate=direction * 2 * np.pi * tps * env, height=height)


def twirl(t, duration, rng, turns_per_s=None) -> MoveOutput:
    """A fast spin with an arm raised overhead, as a salsa follow turns under the lead's arm."""
    out = spin(t, duration, rng, turns_per_s=turns_per_s, arms="out")
    env = _envelope(t, duration, min(0.5, duration / 3))
    out.angles["RightArm"] = _vec(y=2.3 * env, n=len(t))
    out.angles["LeftUpLeg"] = _vec(x=-0.1 * env, n=len(t))
    out.angles["LeftLeg"] = _vec(x=0.3 * env, n=len(t))
    return out


def sway(t, duration, rng, frequency=None, amplitude=None) -> MoveOutput:
    """Hips swaying side to side with the weight shifting between the feet."""
    f = rng.uniform(0.8, 1.6) if frequency is None else frequency
    amp = rng.uniform(0.12, 0.25) if amplitude is None else amplitude
    env = _envelope(t, duration, 0.4)
    s = np.sin(2 * np.pi * f * t) * env
    n = len(t)
    a: Angles = {
        "Hips": _vec(y=amp * s, z=0.3 * amp * np.cos(2 * np.pi * f * t) * env, n=n),
        "LowerBack": _vec(y=-0.7 * amp * s, n=n),
        "Spine1": _vec(y=-0.5 * amp * s, n=n),
        "LeftUpLeg": _vec(y=-amp * s, x=-0.1 * np.clip(s, 0, None), n=n),
        "RightUpLeg": _vec(y=-amp * s, x=-0.1 * np.clip(-s, 0, None), n=n),
        "LeftLeg": _vec(x=0.25 * np.clip(s, 0, None), n=n),
        "RightLeg": _vec(x=0.25 * np.clip(-s, 0, None), n=n),
        "LeftArm": _vec(y=-0.4 * env, x=-0.3 * s, n=n),
        "RightArm": _vec(y=0.4 * env, x=0.3 * s, n=n),
    }
    return _output(t, a, sideways=0.25 * amp * 2 * np.pi * f * np.cos(2 * np.pi * f * t) * env)


def kick(t, duration, rng, side=None, height=None) -> MoveOutput:
    """A quick front kick: the leg swings up 60-90 degrees and back down."""
    side = rng.choice(["Left", "Right"]) if side is None else side
    lift = rng.uniform(1.0, 1.55) if height is None else height
    n = len(t)
    # A fast bump centred in the move, about a quarter second wide.
    centre, width = duration / 2, min(0.28, duration / 3)
    bump = np.exp(-0.5 * ((t - centre) / (width / 2.5)) ** 2)
    prep = _envelope(t, duration, duration / 3)
    other = "Right" if side == "Left" else "Left"
    a: Angles = {
        f"{side}UpLeg": _vec(x=-lift * bump + 0.15 * prep * (1 - bump), n=n),
        f"{side}Leg": _vec(x=0.9 * prep * (1 - bump) + 0.1 * bump, n=n),
        f"{side}Foot": _vec(x=-0.3 * bump, n=n),
        f"{other}Leg": _vec(x=0.15 * prep, n=n),
        "Spine1": _vec(x=-0.15 * bump, n=n),
        "LeftArm": _vec(y=-0.6 * prep, n=n),
        "RightArm": _vec(y=0.6 * prep, n=n),
    }
    return _output(t, a, height=-0.02 * prep)


def jump(t, duration, rng, height=None) -> MoveOutput:
    """A jump: crouch, take off, a ballistic flight, land and recover."""
    h = rng.uniform(0.12, 0.3) if height is None else height
    flight = 2 * np.sqrt(2 * h / 9.81)
    t0 = max((duration - flight) / 2, 0.05)  # take-off time
    n = len(t)
    tau = np.clip(t - t0, 0, flight)
    airborne = (t >= t0) & (t <= t0 + flight)
    z = np.where(airborne, np.sqrt(2 * 9.81 * h) * tau - 0.5 * 9.81 * tau**2, 0.0)
    # Crouch before take-off and after landing.
    crouch = np.exp(-0.5 * ((t - t0 + 0.12) / 0.1) ** 2) + np.exp(
        -0.5 * ((t - t0 - flight - 0.1) / 0.1) ** 2
    )
    crouch = np.clip(crouch, 0, 1)
    # Tuck in the air: rises from take-off and returns by landing, without a step.
    air = np.sin(np.pi * np.clip((t - t0) / flight, 0.0, 1.0))
    a: Angles = {
        "LeftUpLeg": _vec(x=-0.9 * crouch - 0.2 * air, n=n),
        "RightUpLeg": _vec(x=-0.9 * crouch - 0.2 * air, n=n),
        "LeftLeg": _vec(x=1.5 * crouch + 0.3 * air, n=n),
        "RightLeg": _vec(x=1.5 * crouch + 0.3 * air, n=n),
        "LeftFoot": _vec(x=-0.6 * crouch + 0.4 * air, n=n),
        "RightFoot": _vec(x=-0.6 * crouch + 0.4 * air, n=n),
        "LowerBack": _vec(x=0.35 * crouch, n=n),
        "LeftArm": _vec(x=0.5 * crouch - 1.0 * air, n=n),
        "RightArm": _vec(x=0.5 * crouch - 1.0 * air, n=n),
    }
    return _output(t, a, height=z - 0.3 * crouch)


def bow(t, duration, rng, depth=None) -> MoveOutput:
    """A deep bow: the torso folds forward, most of it at the hips with the legs kept upright,
    holds, and rises. ``depth`` (radians) is shared out between the hips and the spine; the
    torso's pitch (the pelvis-to-neck line against the vertical) comes out about 0.9 of it:
    57-76 degrees for the drawn 1.13-1.48."""
    d = rng.uniform(1.13, 1.48) if depth is None else depth
    env = _envelope(t, duration, duration / 3)
    n = len(t)
    a: Angles = {
        "Hips": _vec(x=0.65 * d * env, n=n),  # the pelvis tips forward
        "LeftUpLeg": _vec(x=-0.65 * d * env, n=n),  # the legs stay under it
        "RightUpLeg": _vec(x=-0.65 * d * env, n=n),
        "LowerBack": _vec(x=0.2 * d * env, n=n),
        "Spine": _vec(x=0.1 * d * env, n=n),
        "Spine1": _vec(x=0.05 * d * env, n=n),
        "LeftArm": _vec(y=RELAXED_ARM * env, n=n),
        "RightArm": _vec(y=-RELAXED_ARM * env, n=n),
    }
    return _output(t, a)


def idle(t, duration, rng) -> MoveOutput:
    """Standing, breathing lightly."""
    n = len(t)
    a: Angles = {
        "Spine1": _vec(x=0.02 * np.sin(2 * np.pi * 0.3 * t), n=n),
        "LeftArm": _vec(y=RELAXED_ARM, n=n),
        "RightArm": _vec(y=-RELAXED_ARM, n=n),
    }
    return _output(t, a)


MOVES: dict[str, Callable[..., MoveOutput]] = {
    "idle": idle,
    "walk": walk,
    "turn": turn,
    "spin": spin,
    "twirl": twirl,
    "sway": sway,
    "kick": kick,
    "jump": jump,
    "bow": bow,
}

# Typical durations (seconds) a move is drawn with in a random dance.
_DURATIONS = {
    "idle": (0.6, 1.2),
    "walk": (1.5, 3.0),
    "turn": (1.0, 1.8),
    "spin": (1.6, 3.0),
    "twirl": (1.2, 2.2),
    "sway": (2.0, 3.5),
    "kick": (0.8, 1.2),
    "jump": (0.9, 1.3),
    "bow": (2.4, 3.4),
}


@dataclass
class MoveSpec:
    """One move of a dance: its name, duration and keyword parameters."""

    name: str
    duration: float
    params: dict = field(default_factory=dict)


def _blend_weights(n_frames: list[int], fade: int) -> list[np.ndarray]:
    """Per-move weights over the whole timeline, cross-fading ``fade`` frames at each boundary."""
    total = sum(n_frames)
    starts = np.cumsum([0, *n_frames[:-1]])
    frames = np.arange(total)
    out = []
    for i, (s, n) in enumerate(zip(starts, n_frames, strict=True)):
        w = np.zeros(total)
        lo = s - (fade // 2 if i > 0 else 0)
        hi = s + n + (fade - fade // 2 if i < len(n_frames) - 1 else 0)
        ramp_in = _smoothstep((frames - lo) / max(fade, 1)) if i > 0 else 1.0
        ramp_out = _smoothstep((hi - frames) / max(fade, 1)) if i < len(n_frames) - 1 else 1.0
        w = np.where((frames >= lo) & (frames < hi), ramp_in * ramp_out, 0.0)
        out.append(w)
    norm = np.sum(out, axis=0)
    return [w / norm for w in out]


def compose(
    moves: list[MoveSpec],
    joint_names: tuple[str, ...],
    floor_height: float,
    fps: float = 30.0,
    seed: int = 0,
    fade: float = 0.3,
    *,
    name: str = "dance",
) -> Motion:
    """A motion from a sequence of moves, cross-faded, with the root trajectory integrated.

    Args:
        moves: the moves in order.
        joint_names: the avatar's joints (``Avatar.joint_names``); ``Hips`` is the root.
        floor_height: the avatar's root height standing (``Avatar.floor_height``).
        fps: frame rate.
        seed: seeds the parameters that a move's ``params`` leave open.
        fade: cross-fade between moves, seconds.
        name: the motion's name.

    Returns:
        A :class:`~loosefit.types.Motion` starting at the origin, facing -Y.
    """
    if not moves:
        raise LoosefitInputError("compose", "moves", "at least one move", "none")
    rng = np.random.default_rng(seed)
    outputs, n_frames = [], []
    fade_frames = int(round(fade * fps))
    for m in moves:
        if m.name not in MOVES:
            raise LoosefitInputError("compose", "moves.name", f"one of {list(MOVES)}", repr(m.name))
        if not m.duration > 0:
            raise LoosefitInputError("compose", f"moves[{m.name}].duration", "> 0", m.duration)
        n = max(int(round(m.duration * fps)), 1)
        # Each move is evaluated over its own frames plus the fade margins.
        pad = fade_frames
        t = (np.arange(-pad, n + pad) / fps).clip(0, m.duration)
        outputs.append((MOVES[m.name](t, m.duration, rng, **m.params), pad))
        n_frames.append(n)
    total = sum(n_frames)
    weights = _blend_weights(n_frames, fade_frames)
    starts = np.cumsum([0, *n_frames[:-1]])

    def place(arr: np.ndarray, i: int) -> np.ndarray:
        """A move's per-frame values on the global timeline (held at the ends)."""
        out_i, pad = outputs[i]
        idx = np.clip(np.arange(total) - starts[i] + pad, 0, len(arr) - 1)
        return arr[idx]

    J = len(joint_names)
    aa = np.zeros((total, J, 3))
    root = {k: np.zeros(total) for k in ("forward", "sideways", "turn_rate", "height")}
    for i, (out, _) in enumerate(outputs):
        w = weights[i]
        for jn, v in out.angles.items():
            if jn not in joint_names:
                raise LoosefitInputError(
                    "compose",
                    "joint_names",
                    f"a skeleton with joint '{jn}'",
                    f"{list(joint_names)}",
                )
            aa[:, joint_names.index(jn)] += w[:, None] * place(v, i)
        for k in root:
            root[k] += w * place(getattr(out, k), i)

    # Integrate the root trajectory in the heading frame.
    dt = 1.0 / fps
    heading = np.concatenate([[0.0], np.cumsum(root["turn_rate"][:-1] * dt)])
    fwd = np.stack([np.sin(heading), -np.cos(heading)], 1)  # facing -Y at heading 0
    left = np.stack([np.cos(heading), np.sin(heading)], 1)
    vel = root["forward"][:, None] * fwd + root["sideways"][:, None] * left
    xy = np.concatenate([[[0.0, 0.0]], np.cumsum(vel[:-1] * dt, axis=0)])
    translation = np.concatenate([xy, (floor_height + root["height"])[:, None]], 1)

    rotations = axis_angle_to_matrix(aa.reshape(-1, 3)).reshape(total, J, 3, 3)
    yaw = axis_angle_to_matrix(np.stack([np.zeros(total), np.zeros(total), heading], 1))
    rotations[:, 0] = yaw @ rotations[:, 0]
    return Motion(
        joint_names,
        rotations.astype(np.float32),
        translation.astype(np.float32),
        fps,
        name=name,
        meta={"moves": [(m.name, m.duration, m.params) for m in moves], "seed": seed},
    )


def random_dance(
    joint_names: tuple[str, ...],
    floor_height: float,
    duration: float,
    seed: int,
    fps: float = 30.0,
    moves: tuple[str, ...] = ("walk", "turn", "spin", "twirl", "sway", "kick", "jump"),
    *,
    name: str | None = None,
) -> Motion:
    """A dance of random moves drawn from ``moves``, about ``duration`` seconds long.

    Starts and ends standing (``idle``); each move's duration and parameters are
    drawn from ``seed``, so the same seed gives the same dance.
    """
    rng = np.random.default_rng(seed)
    specs = [MoveSpec("idle", 0.5)]
    elapsed = 0.5
    while elapsed < duration - 0.5:
        m = str(rng.choice(moves))
        lo, hi = _DURATIONS[m]
        d = float(min(rng.uniform(lo, hi), max(duration - 0.5 - elapsed, lo)))
        specs.append(MoveSpec(m, d))
        elapsed += d
    specs.append(MoveSpec("idle", 0.5))
    return compose(
        specs, joint_names, floor_height, fps=fps, seed=seed, name=name or f"dance_{seed:04d}"
    )


def named_motion(
    name: str, joint_names: tuple[str, ...], floor_height: float, seed: int = 0, fps: float = 30.0
) -> Motion:
    """A short demonstration of one move (e.g. ``"spin"``) or ``"dance"``, framed by idle."""
    if name == "dance":
        return random_dance(joint_names, floor_height, 12.0, seed, fps)
    if name not in MOVES:
        raise LoosefitInputError("motion name", "name", f"one of {['dance', *MOVES]}", repr(name))
    lo, hi = _DURATIONS[name]
    specs = [MoveSpec("idle", 0.5), MoveSpec(name, hi), MoveSpec("idle", 0.8)]
    return compose(specs, joint_names, floor_height, fps=fps, seed=seed, name=name)
