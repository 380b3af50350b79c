"""Rollout: a motion to an animated garment, frame after frame (paper 3.3 at inference).

A rollout starts as the simulator does: the body stands in the rest pose for
a few frames (``warm_frames``, which also warm the GRU up), then blends into
the motion's first frame (``blend_seconds``), and the garment starts from its
settled drape on the rest pose (:func:`loosefit.sim.driver.settle`). From then
on each frame's garment is decoded from ``Z_t = E(M_t, V_{t-1})`` and fed back
as the next frame's previous state. Training runs the same timeline, so the
encoder has seen every kind of frame it meets here.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import torch

from loosefit.body.chain import rollout_timeline
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


@dataclass(frozen=True)
class Stages:
    """Which stages run after the decoders (each can be switched off)."""

    detail: bool = True  # paper 3.4, when the model carries a detail stage
    lengths: bool = True  # edges back to their rest lengths (physics.LengthRestorer)
    collision: bool = True  # paper 3.5
    feedback: bool = False  # the garment after them is the next frame's previous state
    overlap: bool = True  # without feedback: they run on a second thread beside the motion stage


MOTION_ONLY = Stages(detail=False, lengths=False, collision=False)  # the motion stage alone


class RolloutError(RuntimeError):
    """A rollout produced NaN or a garment far from the body; the message names the frame."""


@dataclass
class RolloutConfig:
    """The timeline before a motion's first frame, and when a rollout has failed."""

    warm_frames: int = 5  # rest-pose frames before the blend
    blend_seconds: float = 0.5  # rest pose to the motion's first frame (the simulator's blend)
    max_distance: float = 3.0  # m from the root: a vertex farther away means the rollout diverged


def timeline(
    motion: Motion, floor_height: float, config: RolloutConfig
) -> tuple[torch.Tensor, torch.Tensor, int]:
    """The rest frames, the blend and the motion, as one sequence.

    Returns:
        rotations (P + T, J, 3, 3) float32, root translations (P + T, 3) float32,
        and P, the number of frames before the motion's first.
    """
    rot, root, P = rollout_timeline(motion, floor_height, config.warm_frames, config.blend_seconds)
    return torch.from_numpy(rot), torch.from_numpy(root), P


def motion_root_frames(
    motion: Motion, floor_height: float, config: RolloutConfig | None = None
) -> tuple[torch.Tensor, torch.Tensor, int]:
    """The root frames of the motion's own frames on the rollout timeline.

    Returns:
        H (T, 3, 3) headings and p (T, 3) origins, float32, and P, the frames before.
    """
    rot, root, P = timeline(motion, floor_height, config or RolloutConfig())
    H, p = root_frames(rot[P:].double(), root[P:].double())
    return H.float(), p.float(), P


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
        stage_seconds: wall-clock seconds per stage ("motion", "detail", "collision"),
            where measured.
        stage_cpu_seconds: the same stages' CPU time on the threads that ran them
            (``time.thread_time``: unlike the wall clock, not lengthened by other work on
            a shared machine).
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


@torch.no_grad()
def rollout(
    generative: GarmentGenerativeModel,
    encoder: DynamicMotionEncoder,
    motion: Motion,
    rest_state: torch.Tensor,
    floor_height: float,
    config: RolloutConfig | None = None,
    progress: Callable[[int, int], None] | None = None,
    truth: np.ndarray | None = None,
    restart_every: int | None = None,
    detail: Callable[[torch.Tensor, torch.Tensor], torch.Tensor] | None = None,
    collide: Callable[[int, torch.Tensor], object] | None = None,
    feedback: bool = False,
    overlap: bool = True,
    lengths: Callable[[torch.Tensor], torch.Tensor] | None = None,
    step: Callable | None = None,
) -> RolloutResult:
    """Animate the garment through ``motion``.

    Args:
        generative: the trained generative model (its decoders).
        encoder: the trained dynamic motion encoder.
        motion: T frames on the skeleton the encoder was trained on.
        rest_state: (V, 3) the settled drape in the rest pose's root frame.
        floor_height: the avatar's standing root height.
        config: the preroll and the divergence limit.
        progress: called as ``progress(done, total)`` every frame.
        truth: (T, V, 3) world positions of the simulated garment on the motion's
            frames; with ``restart_every``, a measurement of drift: every
            ``restart_every`` motion frames the previous state is reset to the truth's
            previous frame, so that every frame is predicted at most that many frames
            after a true state (the GRU's state depends on the motion alone and runs on).
        restart_every: frames between restarts (needs ``truth``).
        detail: the detail generator (paper 3.4), ``(V_t, Z_t) -> I_de`` on garments
            (n, V, 3) in their root frames and codes (n, Z); None skips it.
        collide: collision handling (paper 3.5), ``collide(motion_frame, garment (V, 3)
            world) -> CollisionResult``; None skips it.
        feedback: feed the garment after detail and collision back as the next frame's
            previous state (else the decoders' own output, what the encoder was trained
            on, is fed back and the later stages run over all frames at once).
        overlap: without feedback, run detail and collision handling on a second
            thread, ``chunk`` frames at a time, while the motion stage goes on with the
            next frames: the same results; with two cores a frame costs about the
            slower of the two instead of their sum.
        lengths: between detail and collision, ``(n, V, 3) -> (n, V, 3)`` world garments
            with their edges back at rest length (a
            :class:`~loosefit.model.physics.LengthRestorer`); None skips it.
        step: the motion stage's network call, ``step(features (1, F), previous (1, V, 3),
            hidden (1, G)) -> (Z_t (1, Z), hidden (1, G), garment (1, V, 3))``, garments
            in the frame's root frame; None: ``encoder`` and ``generative``'s decoders in
            PyTorch (:class:`~loosefit.inference.onnx_stages.OnnxStep` runs them in
            onnxruntime).

    Returns:
        :class:`RolloutResult`.

    Raises:
        RolloutError: NaN, or a vertex farther than ``config.max_distance`` from the root.
    """
    config = config or RolloutConfig()
    generative.eval()
    encoder.eval()
    device = rest_state.device
    rot, root, P = timeline(motion, floor_height, config)
    joints = feature_joints(motion.joint_names, encoder.config.joints)
    feats = motion_features(rot, root, motion.fps, floor_height, joints).to(device)
    H, p = (a.float().to(device) for a in root_frames(rot.double(), root.double()))
    total = len(feats)
    out = torch.empty(motion.num_frames, encoder.num_vertices, 3)
    hidden = encoder.initial_hidden(1, device)
    prev = rest_state[None].float()
    if restart_every is not None:
        if truth is None or restart_every < 1:
            raise ValueError("restart_every needs truth and must be at least 1")
        if truth.shape != (motion.num_frames, encoder.num_vertices, 3):
            raise ValueError(
                f"truth: expected {(motion.num_frames, encoder.num_vertices, 3)}, "
                f"found {truth.shape}"
            )
        truth_t = torch.as_tensor(truth, dtype=torch.float32, device=device)
    refine = detail is not None or collide is not None or lengths is not None
    codes = torch.empty(motion.num_frames, encoder.latent)
    decoded = torch.empty(motion.num_frames, encoder.num_vertices, 3) if refine else None
    collisions: list | None = [] if collide is not None else None
    stage = {"motion": 0.0, "detail": 0.0, "lengths": 0.0, "collision": 0.0}
    cpu = dict.fromkeys(stage, 0.0)  # the same, thread CPU time
    later = _Later(detail, collide, H[P:].cpu(), p[P:].cpu(), device, lengths) if refine else None
    pool = ThreadPoolExecutor(1) if refine and overlap and not feedback else None
    jobs: list = []
    start = t0 = time.perf_counter()
    c0 = time.thread_time()
    for t in range(total):
        m = t - P
        if restart_every is not None and m > 0 and m % restart_every == 0:
            prev = to_root_frame(truth_t[m - 1 : m], H[t - 1 : t], p[t - 1 : t])
        if t > 0:
            prev = change_frame(prev, H[t - 1 : t], p[t - 1 : t], H[t : t + 1], p[t : t + 1])
        if step is None:
            z, hidden = encoder(feats[t : t + 1], prev, hidden)
            prev = generative.decode(z)["vertices"]
        else:
            z, hidden, prev = step(feats[t : t + 1], prev, hidden)
        where = f"motion frame {t - P}" if t >= P else f"preroll frame {t}"
        check_garment(prev, config.max_distance, where)
        if t >= P:
            world = from_root_frame(prev, H[t : t + 1], p[t : t + 1])
            codes[m] = z[0].cpu()
            if refine:
                decoded[m] = world[0].cpu()
            if refine and feedback:  # this frame through the later stages, then fed back
                stage["motion"] += time.perf_counter() - t0
                cpu["motion"] += time.thread_time() - c0
                part, records = later(decoded, codes, m, m + 1)
                world = part.to(device)
                if collisions is not None:
                    collisions.extend(records)
                prev = to_root_frame(world, H[t : t + 1], p[t : t + 1])
                t0, c0 = time.perf_counter(), time.thread_time()
            out[m] = world[0].cpu()
            if pool is not None and (m + 1) % later.chunk == 0:  # a chunk to refine
                jobs.append(pool.submit(later, decoded, codes, m + 1 - later.chunk, m + 1))
        if progress is not None:
            progress(t + 1, total)
    stage["motion"] += time.perf_counter() - t0
    cpu["motion"] += time.thread_time() - c0
    if later is not None and not feedback:
        T = motion.num_frames
        done = len(jobs) * later.chunk
        try:
            parts = [job.result() for job in jobs]
        finally:
            if pool is not None:
                pool.shutdown(cancel_futures=True)
        parts += [
            later(decoded, codes, s, min(s + later.chunk, T)) for s in range(done, T, later.chunk)
        ]
        for s, (part, records) in zip(range(0, T, later.chunk), parts, strict=True):
            out[s : s + len(part)] = part
            if collisions is not None:
                collisions.extend(records)
    if later is not None:
        for k in ("detail", "lengths", "collision"):
            stage[k] += later.seconds[k]
            cpu[k] += later.cpu_seconds[k]
    seconds = time.perf_counter() - start if pool is not None else sum(stage.values())
    return RolloutResult(
        out.numpy(),
        seconds,
        total,
        codes.numpy(),
        decoded.numpy() if refine else None,
        collisions,
        {k: v for k, v in stage.items() if v > 0},
        {k: v for k, v in cpu.items() if stage[k] > 0},
    )


@torch.no_grad()
def rollout_batch(
    generative: GarmentGenerativeModel,
    encoder: DynamicMotionEncoder,
    motions: list[Motion],
    rest_state: torch.Tensor,
    floor_height: float,
    config: RolloutConfig | None = None,
    progress: Callable[[int, int], None] | None = None,
    step: Callable | None = None,
) -> list[RolloutResult]:
    """The motion stage of :func:`rollout` for N motions at once (N characters): one network
    call per frame for all of them. Shorter motions are padded by holding their last frame
    (those frames are dropped from their results).

    Args:
        motions: N motions on the encoder's skeleton, at one frame rate.
        rest_state, floor_height, config, progress: as for :func:`rollout`.
        step: as for :func:`rollout`, on the batch: ``step(features (N, F), previous
            (N, V, 3), hidden (N, G)) -> (Z_t (N, Z), hidden (N, G), garment (N, V, 3))``
            (None: the encoder and the decoders in PyTorch).

    Returns:
        One :class:`RolloutResult` per motion (its ``seconds`` the batch's, shared).

    Raises:
        RolloutError: NaN, or a vertex farther than ``config.max_distance`` from the root,
            naming the motion.
    """
    config = config or RolloutConfig()
    generative.eval()
    encoder.eval()
    device = rest_state.device
    if not motions or len({round(m.fps, 6) for m in motions}) != 1:
        raise ValueError("rollout_batch needs at least one motion, all at one frame rate")
    lines = [timeline(m, floor_height, config) for m in motions]
    P = lines[0][2]
    total = max(len(rot) for rot, _, _ in lines)

    def padded(x: torch.Tensor) -> torch.Tensor:
        return torch.cat([x, x[-1:].expand(total - len(x), *x.shape[1:])]) if len(x) < total else x

    joints = feature_joints(motions[0].joint_names, encoder.config.joints)
    feats = torch.stack(
        [
            padded(motion_features(rot, root, m.fps, floor_height, joints))
            for (rot, root, _), m in zip(lines, motions, strict=True)
        ]
    )
    frames = [root_frames(rot.double(), root.double()) for rot, root, _ in lines]
    H = torch.stack([padded(h) for h, _ in frames]).float().to(device)  # (N, total, 3, 3)
    p = torch.stack([padded(q) for _, q in frames]).float().to(device)  # (N, total, 3)
    feats = feats.to(device)
    N, T = len(motions), total - P
    out = torch.empty(N, T, encoder.num_vertices, 3)
    codes = torch.empty(N, T, encoder.latent)
    hidden = encoder.initial_hidden(N, device)
    prev = rest_state[None].float().expand(N, -1, -1)
    start = time.perf_counter()
    for t in range(total):
        if t > 0:
            prev = change_frame(prev, H[:, t - 1], p[:, t - 1], H[:, t], p[:, t])
        if step is None:
            z, hidden = encoder(feats[:, t], prev, hidden)
            prev = generative.decode(z)["vertices"]
        else:
            z, hidden, prev = step(feats[:, t], prev, hidden)
        far = prev.norm(dim=-1).amax(-1)  # (N,) m from the root, NaN where NaN
        bad = (~(far <= config.max_distance)).nonzero()
        if len(bad):  # the first character that diverged, said as rollout() says it
            i = int(bad[0, 0])
            where = f"motion frame {t - P}" if t >= P else f"preroll frame {t}"
            check_garment(
                prev[i : i + 1], config.max_distance, f"{where} of motion {i} ('{motions[i].name}')"
            )
        if t >= P:
            out[:, t - P] = from_root_frame(prev, H[:, t], p[:, t]).cpu()
            codes[:, t - P] = z.cpu()
        if progress is not None:
            progress(t + 1, total)
    seconds = time.perf_counter() - start
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


def collision_record(result) -> dict:
    """A collision result's figures, without its vertices."""
    return {k: v for k, v in vars(result).items() if k != "vertices"}


class _Later:
    """Detail enhancement, edge lengths and collision handling of decoded frames, a chunk at a time
    (after the motion stage or beside it on a second thread), or one frame at a time
    when fed back; busy seconds per stage in ``seconds``."""

    chunk = 64

    def __init__(self, detail, collide, H, p, device, lengths=None) -> None:
        self.detail, self.collide, self.H, self.p, self.device = detail, collide, H, p, device
        self.lengths = lengths
        self.seconds = {"detail": 0.0, "lengths": 0.0, "collision": 0.0}
        self.cpu_seconds = dict.fromkeys(self.seconds, 0.0)  # thread CPU time, the same

    def __call__(
        self, decoded: torch.Tensor, codes: torch.Tensor, s: int, e: int
    ) -> tuple[torch.Tensor, list[dict]]:
        """Motion frames [s, e) of decoded (T, V, 3) world garments and their codes
        (T, latent): the refined garments (e - s, V, 3) and collision records."""
        with torch.no_grad():  # grad mode is per thread
            out = decoded[s:e].clone()
            t0, c0 = time.perf_counter(), time.thread_time()
            if self.detail is not None:
                h, q = self.H[s:e].to(self.device), self.p[s:e].to(self.device)
                local = to_root_frame(out.to(self.device), h, q)
                local = local + self.detail(local, codes[s:e].to(self.device))
                out = from_root_frame(local, h, q).cpu()
            t1, c1 = time.perf_counter(), time.thread_time()
            if self.detail is not None:  # a stage that did not run takes no time
                self.seconds["detail"] += t1 - t0
                self.cpu_seconds["detail"] += c1 - c0
            if self.lengths is not None:
                out = self.lengths(out)
                t0, t1, c0, c1 = t1, time.perf_counter(), c1, time.thread_time()
                self.seconds["lengths"] += t1 - t0
                self.cpu_seconds["lengths"] += c1 - c0
            records = []
            if self.collide is not None:
                for i in range(len(out)):
                    result = self.collide(s + i, out[i].to(self.device))
                    out[i] = result.vertices.cpu()
                    records.append(collision_record(result))
                self.seconds["collision"] += time.perf_counter() - t1
                self.cpu_seconds["collision"] += time.thread_time() - c1
        return out, records


def refine(
    result: RolloutResult,
    motion: Motion,
    floor_height: float,
    config: RolloutConfig,
    detail=None,
    collide=None,
    device="cpu",
    lengths=None,
) -> RolloutResult:
    """Detail enhancement and collision handling (as :func:`rollout` runs them after the
    motion stage) of a motion-stage result, e.g. one of :func:`rollout_batch`'s, in place:
    ``decoded`` keeps the decoders' garments, ``vertices`` gets the refined ones."""
    if detail is None and collide is None and lengths is None:
        return result
    H, p, _ = motion_root_frames(motion, floor_height, config)
    later = _Later(detail, collide, H, p, device, lengths)
    decoded = torch.from_numpy(result.vertices)
    codes = torch.from_numpy(result.codes)
    parts, records = [], []
    for s in range(0, motion.num_frames, later.chunk):
        part, rec = later(decoded, codes, s, min(s + later.chunk, motion.num_frames))
        parts.append(part)
        records.extend(rec)
    result.decoded, result.vertices = result.vertices, torch.cat(parts).numpy()
    result.collisions = records if collide is not None else None
    result.stage_seconds = {
        **(result.stage_seconds or {}),
        **{k: v for k, v in later.seconds.items() if v > 0},
    }
    return result


@torch.no_grad()
def carried_drape(
    motion: Motion,
    rest_state: torch.Tensor,
    floor_height: float,
    config: RolloutConfig | None = None,
) -> RolloutResult:
    """The settled drape carried rigidly by the root frame: a garment with no dynamics at all.

    Not a model: the reference that error tables set a learned rollout against (a
    rollout that does no better has learned nothing of the motion). Frame ``t`` is
    ``rest_state`` placed in the root frame (heading and origin) of motion frame ``t``.

    Args:
        motion: T frames.
        rest_state: (V, 3) the settled drape in the rest pose's root frame.
        floor_height: the avatar's standing root height (for the timeline, as in a rollout).
        config: the preroll (only its length matters here).

    Returns:
        :class:`RolloutResult` with (T, V, 3) world positions.
    """
    t0 = time.perf_counter()
    H, p, P = motion_root_frames(motion, floor_height, config)
    rest = rest_state.detach().float().cpu()[None].expand(len(H), -1, -1)
    out = from_root_frame(rest, H, p)
    return RolloutResult(out.numpy(), time.perf_counter() - t0, P + len(H))


@torch.no_grad()
def reconstruction(
    generative: GarmentGenerativeModel,
    motion: Motion,
    truth: np.ndarray,
    floor_height: float,
    config: RolloutConfig | None = None,
    chunk: int = 128,
) -> RolloutResult:
    """The simulated garment through the generative model: its own code Z*, decoded.

    Not a model either: the floor under any motion encoder's error, since a motion
    encoder can do no better than map each frame to the code the generative encoder
    gives the simulated garment (Eq. 12's Z*) and the frozen decoders decode it.

    Args:
        generative: the generative stage.
        motion: T frames (only the root frames matter).
        truth: (T, V, 3) the simulated garment, world positions.
        floor_height, config: as in a rollout (the root frames of the motion frames).
        chunk: frames per network call.

    Returns:
        :class:`RolloutResult` with (T, V, 3) world positions.
    """
    t0 = time.perf_counter()
    H, p, _ = motion_root_frames(motion, floor_height, config)
    local = to_root_frame(torch.as_tensor(truth, dtype=torch.float32), H, p)
    world = from_root_frame(generative.reconstruct_all(local, chunk), H, p)
    return RolloutResult(world.numpy(), time.perf_counter() - t0, int(len(local)))
