"""Rollout: a motion to an animated garment, frame after frame (paper 3.3 at inference).

The timeline (:mod:`loosefit.inference.timeline`) puts a few rest-pose frames and a blend
before the motion; the garment starts from its settled drape on the rest pose. Each frame:

1. the previous garment is moved into this frame's root frame;
2. the motion stage (:class:`MotionStage`) encodes ``Z_t = E(M_t, V_{t-1})`` and decodes
   this frame's garment, which is checked (:func:`check_garment`);
3. on the motion's own frames, the later stages (:mod:`loosefit.inference.stages`: detail,
   edge lengths, collision) run over it: beside the motion stage on a second thread, a
   chunk of frames at a time (``overlap``), after it, or frame by frame with their output
   fed back as the next previous garment (``feedback``).

What a caller measures (stage timings, drift against a simulation) comes in as
:class:`RolloutHooks`; :class:`RolloutOptions` says which later stages run and how.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import torch

from loosefit.inference.stages import Stage, StageClock, StageFrames, run_stages
from loosefit.inference.timeline import RolloutConfig, Timeline, rollout_timeline
from loosefit.model.generative import GarmentGenerativeModel
from loosefit.model.motion_encoder import DynamicMotionEncoder
from loosefit.model.motion_features import (
    feature_joints,
    from_root_frame,
    motion_features,
    root_frames,
    to_root_frame,
)
from loosefit.types import Motion

# the motion stage's network call: features (B, F), previous garments (B, V, 3) and GRU
# state (B, G) -> Z_t (B, Z), the next state (B, G) and the garments (B, V, 3), garments in
# their frames' root frames (an OnnxStep runs it in onnxruntime)
StepFunction = Callable[
    [torch.Tensor, torch.Tensor, torch.Tensor], tuple[torch.Tensor, torch.Tensor, torch.Tensor]
]


class RolloutError(RuntimeError):
    """A rollout produced NaN or a garment far from the body; the message names the frame."""


def timeline(motion: Motion, floor_height: float, config: RolloutConfig) -> Timeline:
    """The rest frames, the blend and the motion, as one sequence.

    Returns:
        :class:`~loosefit.inference.timeline.Timeline` of tensors: rotations
        (P + T, J, 3, 3) float32, root translations (P + T, 3) float32, and P, the number
        of frames before the motion's first.
    """
    rot, root, P = rollout_timeline(motion, floor_height, config.warm_frames, config.blend_seconds)
    return Timeline(torch.from_numpy(rot), torch.from_numpy(root), P)


class RootFrames(NamedTuple):
    """The root frames of a motion's own frames on the rollout timeline, float32."""

    headings: torch.Tensor  # (T, 3, 3) H: each frame's heading (a rotation about the vertical)
    origins: torch.Tensor  # (T, 3) p: each frame's origin, the root's position, m
    preroll: int  # P: the frames before the motion's first on the timeline


class RolloutInputs(NamedTuple):
    """What a rollout reads of a motion, every frame of its timeline (P + T frames)."""

    features: torch.Tensor  # (P + T, F) the motion encoder's features
    headings: torch.Tensor  # (P + T, 3, 3) H: each frame's root heading
    origins: torch.Tensor  # (P + T, 3) p: each frame's origin, the root's position, m
    preroll: int  # P: the frames before the motion's first


def motion_root_frames(
    motion: Motion, floor_height: float, config: RolloutConfig | None = None
) -> RootFrames:
    """The root frames of the motion's own frames on the rollout timeline.

    Returns:
        :class:`RootFrames`: H (T, 3, 3) headings and p (T, 3) origins, float32, and P,
        the frames before.
    """
    rot, root, P = timeline(motion, floor_height, config or RolloutConfig())
    H, p = root_frames(rot[P:].double(), root[P:].double())
    return RootFrames(H.float(), p.float(), P)


@torch.no_grad()
def latent_codes(
    generative: GarmentGenerativeModel, vertices: torch.Tensor, chunk: int = 128
) -> torch.Tensor:
    """(T, latent) the generative encoder's means (Z*) of garments (T, V, 3) in their root
    frames, ``chunk`` frames per network call; on the CPU."""
    return generative.encode_all(vertices, chunk)


def change_frame(
    x: torch.Tensor, H0: torch.Tensor, p0: torch.Tensor, H1: torch.Tensor, p1: torch.Tensor
) -> torch.Tensor:
    """Points (B, V, 3) in root frames (H0, p0) to root frames (H1, p1); H (B, 3, 3), p (B, 3)."""
    return to_root_frame(from_root_frame(x, H0, p0), H1, p1)


def check_garment(x: torch.Tensor, limit: float, where: str) -> None:
    """Raise :class:`RolloutError` on NaN in garments (B, V, 3) or a vertex past ``limit`` (m)."""
    if not torch.isfinite(x).all():
        raise RolloutError(f"rollout diverged at {where}: the garment holds NaN")
    far = x.norm(dim=-1).max()
    if far > limit:
        raise RolloutError(
            f"rollout diverged at {where}: a vertex is {float(far):.2f} m from the root "
            f"(limit {limit} m)"
        )


def frame_name(t: int, P: int) -> str:
    """Timeline frame ``t`` in words, P frames before the motion's first."""
    return f"motion frame {t - P}" if t >= P else f"preroll frame {t}"


@dataclass
class RolloutResult:
    """An animated garment.

    Attributes:
        vertices: (T, V, 3) float32 world positions, frame ``t`` on motion frame ``t``.
        seconds: wall-clock seconds of the network work (all P + T frames).
        frames: P + T, the frames computed.
        codes: (T, latent) float32 the motion encoder's Z_t of each motion frame.
        decoded: (T, V, 3) float32 world positions straight from the decoders (before
            detail and collision), or None when no later stage ran.
        collisions: per motion frame, the collision handling's figures (without the
            vertices), or None when it did not run.
        stage_seconds: wall-clock seconds per stage ("motion", "detail", "lengths",
            "collision"), where measured.
        stage_cpu_seconds: the same stages' CPU time on the threads that ran them
            (:class:`~loosefit.inference.stages.StageClock`).
    """

    vertices: np.ndarray
    seconds: float
    frames: int
    codes: np.ndarray | None = None
    decoded: np.ndarray | None = None
    collisions: list | None = None
    stage_seconds: dict | None = None
    stage_cpu_seconds: dict | None = None

    @property
    def frames_per_second(self) -> float:
        return self.frames / max(self.seconds, 1e-9)


@dataclass
class MotionStage:
    """The learned motion stage a rollout runs: the motion encoder and the frozen decoders,
    and where the garment starts."""

    generative: GarmentGenerativeModel  # the decoders (paper 3.2)
    encoder: DynamicMotionEncoder  # E(M_t, V_{t-1}) (paper 3.3)
    rest_state: torch.Tensor  # (V, 3) the settled drape in the rest pose's root frame
    floor_height: float  # the avatar's standing root height (the motion features ask it)
    config: RolloutConfig = field(default_factory=RolloutConfig)  # preroll, divergence limit
    step: StepFunction | None = None  # the network call; None: encoder and decoders in PyTorch

    @property
    def device(self) -> torch.device:
        return self.rest_state.device

    def eval(self) -> MotionStage:
        self.generative.eval()
        self.encoder.eval()
        return self

    def __call__(
        self, features: torch.Tensor, previous: torch.Tensor, hidden: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """One frame for B garments: features (B, F), previous (B, V, 3) in this frame's root
        frame, hidden (B, G) -> Z_t (B, Z), the next hidden (B, G), the garments (B, V, 3)."""
        if self.step is not None:
            return self.step(features, previous, hidden)
        z, hidden = self.encoder(features, previous, hidden)
        return z, hidden, self.generative.decode(z)["vertices"]

    def inputs(self, motion: Motion) -> RolloutInputs:
        """The motion on the rollout timeline, on :attr:`device`.

        Returns:
            :class:`RolloutInputs`: features (P + T, F), root frames H (P + T, 3, 3) and
            p (P + T, 3), float32, and P, the frames before the motion's first.
        """
        rot, root, P = timeline(motion, self.floor_height, self.config)
        joints = feature_joints(motion.joint_names, self.encoder.config.joints)
        feats = motion_features(rot, root, motion.fps, self.floor_height, joints)
        H, p = (a.float().to(self.device) for a in root_frames(rot.double(), root.double()))
        return RolloutInputs(feats.to(self.device), H, p, P)


@dataclass(frozen=True)
class RolloutOptions:
    """Which stages run after the motion stage, and how."""

    stages: Sequence[Stage] = ()  # the later stages, in order (detail, lengths, collision)
    feedback: bool = False  # their output is the next frame's previous state (frame by frame)
    overlap: bool = True  # without feedback: they run on a second thread, a chunk at a time
    chunk: int = 64  # frames per call of the later stages (without feedback)


class RestartFromTruth:
    """A drift measurement: every ``every`` motion frames the previous garment is reset to
    the simulated one of the frame before, so that every frame is predicted at most that
    many frames after a true state (the GRU's state depends on the motion alone and runs on).

    Args:
        truth: (T, V, 3) world positions of the simulated garment on the motion's frames.
        every: motion frames between restarts (at least 1).
        shape: (T, V, 3) the rollout's, that ``truth`` must have.
        device: where the rollout runs.
    """

    def __init__(self, truth: np.ndarray, every: int, shape: tuple, device) -> None:
        if truth is None or every < 1:
            raise ValueError("restart_every needs truth and must be at least 1")
        if truth.shape != tuple(shape):
            raise ValueError(f"truth: expected {tuple(shape)}, found {truth.shape}")
        self.every = every
        self.truth = torch.as_tensor(truth, dtype=torch.float32, device=device)

    def __call__(
        self, frame: int, previous: torch.Tensor, H: torch.Tensor, p: torch.Tensor
    ) -> torch.Tensor:
        """The previous garment (1, V, 3) for motion frame ``frame`` (> 0), in the root frame
        (H (1, 3, 3), p (1, 3)) of the frame before."""
        if frame % self.every:
            return previous
        return to_root_frame(self.truth[frame - 1 : frame], H, p)


@dataclass
class RolloutHooks:
    """What a caller watches or changes in a rollout, apart from the garment itself."""

    progress: Callable[[int, int], None] | None = None  # progress(done, total) every frame
    clock: StageClock = field(default_factory=StageClock)  # seconds per stage
    restart: RestartFromTruth | None = None  # replaces the previous garment (drift)
    # (T, V, 3) root-frame offsets added to each motion frame's garment as shown and as the
    # later stages take it, never to the motion stage's previous state (a realisation of
    # :mod:`loosefit.model.residual`)
    offsets: torch.Tensor | None = None


@torch.no_grad()
def rollout(
    model: MotionStage,
    motion: Motion,
    options: RolloutOptions | None = None,
    hooks: RolloutHooks | None = None,
) -> RolloutResult:
    """Animate the garment through ``motion``.

    Args:
        model: the motion stage (and where the garment starts).
        motion: T frames on the skeleton the encoder was trained on.
        options: the later stages and how they run (default: none).
        hooks: progress, the stage clock, a drift measurement's restarts, a realisation's
            offsets.

    Returns:
        :class:`RolloutResult` (``collisions`` is left to the caller, who holds the
        collision stage's records).

    Raises:
        RolloutError: NaN, or a vertex farther than ``model.config.max_distance`` from the
            root.
    """
    options, hooks = options or RolloutOptions(), hooks or RolloutHooks()
    clock, stages, chunk = hooks.clock, list(options.stages), options.chunk
    model.eval()
    device = model.device
    feats, H, p, P = model.inputs(motion)
    total, T, V = len(feats), motion.num_frames, model.encoder.num_vertices
    out = torch.empty(T, V, 3)
    codes = torch.empty(T, model.encoder.latent)
    decoded = torch.empty(T, V, 3) if stages else None
    motion_H, motion_p = H[P:].cpu(), p[P:].cpu()

    def later(s: int, e: int) -> torch.Tensor:  # motion frames [s, e) through the stages
        frames = StageFrames(decoded[s:e], codes[s:e], motion_H[s:e], motion_p[s:e], s)
        return run_stages(stages, frames, clock)

    pool = ThreadPoolExecutor(1) if stages and options.overlap and not options.feedback else None
    jobs = []
    hidden = model.encoder.initial_hidden(1, device)
    prev = model.rest_state[None].float()
    offsets = hooks.offsets
    if offsets is not None:
        if tuple(offsets.shape) != (T, V, 3):
            raise ValueError(f"offsets: expected {(T, V, 3)}, found {tuple(offsets.shape)}")
        offsets = offsets.to(device=device, dtype=prev.dtype)
    try:
        with clock.measure("rollout"):
            for t in range(total):
                m = t - P
                with clock.measure("motion"):
                    if hooks.restart is not None and m > 0:
                        prev = hooks.restart(m, prev, H[t - 1 : t], p[t - 1 : t])
                    if t > 0:
                        prev = change_frame(
                            prev, H[t - 1 : t], p[t - 1 : t], H[t : t + 1], p[t : t + 1]
                        )
                    z, hidden, prev = model(feats[t : t + 1], prev, hidden)
                    check_garment(prev, model.config.max_distance, frame_name(t, P))
                    if t >= P:
                        shown = prev if offsets is None else prev + offsets[m : m + 1]
                        world = from_root_frame(shown, H[t : t + 1], p[t : t + 1])
                        codes[m] = z[0].cpu()
                        if stages:
                            decoded[m] = world[0].cpu()
                if t >= P and stages and options.feedback:  # through the stages, fed back
                    world = later(m, m + 1).to(device)
                    prev = to_root_frame(world, H[t : t + 1], p[t : t + 1])
                if t >= P:
                    out[m] = world[0].cpu()
                    if pool is not None and (m + 1) % chunk == 0:  # a chunk for the stages
                        jobs.append(pool.submit(later, m + 1 - chunk, m + 1))
                if hooks.progress is not None:
                    hooks.progress(t + 1, total)
            if stages and not options.feedback:  # the chunks the second thread did, the rest
                parts = [job.result() for job in jobs]
                parts += [later(s, min(s + chunk, T)) for s in range(len(jobs) * chunk, T, chunk)]
                for s, part in zip(range(0, T, chunk), parts, strict=True):
                    out[s : s + len(part)] = part
    finally:
        if pool is not None:
            pool.shutdown(cancel_futures=True)
    wall, cpu = clock.measured(["motion", *(s.name for s in stages)])
    seconds = clock.seconds["rollout"] if pool is not None else sum(wall.values())
    return RolloutResult(
        out.numpy(),
        seconds,
        total,
        codes.numpy(),
        decoded.numpy() if stages else None,
        None,
        wall,
        cpu,
    )


@torch.no_grad()
def rollout_batch(
    model: MotionStage,
    motions: list[Motion],
    progress: Callable[[int, int], None] | None = None,
) -> list[RolloutResult]:
    """The motion stage of :func:`rollout` for N motions at once (N characters): one network
    call per frame for all of them (``model.step``, if set, on the batch). Shorter motions
    are padded by holding their last frame (those frames are dropped from their results).

    Args:
        model: as for :func:`rollout`.
        motions: N motions on the encoder's skeleton, at one frame rate.
        progress: called as ``progress(done, total)`` every frame.

    Returns:
        One :class:`RolloutResult` per motion (its ``seconds`` the batch's, shared).

    Raises:
        RolloutError: NaN, or a vertex farther than ``config.max_distance`` from the root,
            naming the motion.
    """
    model.eval()
    device, limit = model.device, model.config.max_distance
    if not motions or len({round(m.fps, 6) for m in motions}) != 1:
        raise ValueError("rollout_batch needs at least one motion, all at one frame rate")
    lines = [model.inputs(m) for m in motions]  # features, H, p, P of each
    P = lines[0][3]
    total = max(len(feats) for feats, _, _, _ in lines)

    def padded(x: torch.Tensor) -> torch.Tensor:
        return torch.cat([x, x[-1:].expand(total - len(x), *x.shape[1:])]) if len(x) < total else x

    feats = torch.stack([padded(f) for f, _, _, _ in lines])  # (N, total, F)
    H = torch.stack([padded(h) for _, h, _, _ in lines])  # (N, total, 3, 3)
    p = torch.stack([padded(q) for _, _, q, _ in lines])  # (N, total, 3)
    N, T = len(motions), total - P
    out = torch.empty(N, T, model.encoder.num_vertices, 3)
    codes = torch.empty(N, T, model.encoder.latent)
    hidden = model.encoder.initial_hidden(N, device)
    prev = model.rest_state[None].float().expand(N, -1, -1)
    clock = StageClock()
    with clock.measure("motion"):
        for t in range(total):
            if t > 0:
                prev = change_frame(prev, H[:, t - 1], p[:, t - 1], H[:, t], p[:, t])
            z, hidden, prev = model(feats[:, t], prev, hidden)
            far = prev.norm(dim=-1).amax(-1)  # (N,) m from the root, NaN where NaN
            bad = (~(far <= limit)).nonzero()
            if len(bad):  # the first character that diverged, said as rollout() says it
                i = int(bad[0, 0])
                where = f"{frame_name(t, P)} of motion {i} ('{motions[i].name}')"
                check_garment(prev[i : i + 1], limit, where)
            if t >= P:
                out[:, t - P] = from_root_frame(prev, H[:, t], p[:, t]).cpu()
                codes[:, t - P] = z.cpu()
            if progress is not None:
                progress(t + 1, total)
    seconds = clock.seconds["motion"]
    return [
        RolloutResult(
            out[i, : m.num_frames].numpy(),
            seconds,
            P + m.num_frames,
            codes[i, : m.num_frames].numpy(),
            None,
            None,
            {"motion": seconds},
        )
        for i, m in enumerate(motions)
    ]


def refine(
    result: RolloutResult,
    motion: Motion,
    model: MotionStage,
    stages: Sequence[Stage],
    chunk: int = 64,
) -> RolloutResult:
    """The later stages (as :func:`rollout` runs them after the motion stage) of a
    motion-stage result, e.g. one of :func:`rollout_batch`'s, in place: ``decoded`` keeps
    the decoders' garments, ``vertices`` gets the refined ones (``collisions`` is left to
    the caller, who holds the collision stage's records)."""
    if not stages:
        return result
    H, p, _ = motion_root_frames(motion, model.floor_height, model.config)
    decoded = torch.from_numpy(result.vertices)
    codes = torch.from_numpy(result.codes)
    clock = StageClock()
    parts = [
        run_stages(stages, StageFrames(decoded[s:e], codes[s:e], H[s:e], p[s:e], s), clock)
        for s in range(0, motion.num_frames, chunk)
        for e in [min(s + chunk, motion.num_frames)]
    ]
    result.decoded, result.vertices = result.vertices, torch.cat(parts).numpy()
    wall, _ = clock.measured([s.name for s in stages])
    result.stage_seconds = {**(result.stage_seconds or {}), **wall}
    return result
