"""Driving the cloth simulator with a motion: one clip, a batch of clips, or the drape alone.

* **Timeline.** The garment first drapes under gravity on the rest pose
  (``settle_seconds``), then the body blends from the rest pose into the
  motion's first frame (``blend_seconds``: slerp of local rotations, lerp of
  the root); recording starts at the motion's first frame, so frame ``t`` of
  the result is motion frame ``t`` (:mod:`loosefit.sim.timeline`).
* **Stepper.** :class:`~loosefit.sim.stepper.ClothSimulator` advances it a frame at a
  time; a killed run goes on from its resume file (:mod:`loosefit.sim.resume`); cloth
  trapped deep in the body can be put back on the skin (:mod:`loosefit.sim.release`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import torch

from loosefit.errors import LoosefitInputError
from loosefit.garment.quality import quality
from loosefit.sim.cloth_config import ClothConfig
from loosefit.sim.release import TrappedRelease, release_parts
from loosefit.sim.resume import Recording, batch_key, read_resume, resumed_release, save_run
from loosefit.sim.stepper import ClothSimulator
from loosefit.sim.timeline import (
    Timeline,
    body_moves,
    collider_meshes,
    collider_parts,
    limb_collider_faces,
    substep_schedule,
    timeline,
)
from loosefit.sim.waist import glued_points
from loosefit.types import GarmentTemplate, Motion

if TYPE_CHECKING:
    from loosefit.body.avatar import Avatar
    from loosefit.body.regions import BodyParts


class SimulationError(RuntimeError):
    """The simulation diverged (NaN, or a vertex flew away); nothing is returned."""


@dataclass
class SimResult:
    """A simulated garment sequence.

    Attributes:
        garment_vertices: (T, V, 3) float32 world positions, one per motion frame.
        faces: (F, 3) int64 garment triangles (the template's).
        fps: frames per second (the motion's).
        seconds_per_frame: wall-clock seconds per simulated frame, settle and blend included.
        preroll_frames: frames simulated before the motion's first frame (settle + blend).
        settled_vertices: (V, 3) float32 garment at the end of the settle phase.
        quality: :func:`quality` of the recorded frames.
        stats: sizes and timings (numbers), for reports.
    """

    garment_vertices: np.ndarray
    faces: np.ndarray
    fps: float
    seconds_per_frame: float
    preroll_frames: int
    settled_vertices: np.ndarray
    quality: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)


def attached_loop(template: GarmentTemplate) -> bool:
    """Whether a garment is held by a closed band (a waistband: ``meta["attachment"]``
    "loop", the default) or by separate points ("points": a dress's straps)."""
    return (template.meta or {}).get("attachment", "loop") == "loop"


def _check_template(template: GarmentTemplate) -> None:
    src = f"garment '{template.name}'"
    if len(template.waist) == 0:
        raise LoosefitInputError(
            src,
            "waist",
            "at least one waistband vertex to attach to the body",
            "none",
            hint="a garment with no waistband would fall off the body",
        )


def _guard(positions: np.ndarray, body: np.ndarray, limit: float, where: str) -> None:
    """Raise :class:`SimulationError` on NaN or a vertex more than ``limit`` from the body's box."""
    bad = ~np.isfinite(positions).all(-1)
    if bad.any():
        raise SimulationError(
            f"cloth simulation diverged at {where}: {int(bad.sum())} NaN vertices"
        )
    lo, hi = body.min(0), body.max(0)
    gap = np.linalg.norm(positions - np.clip(positions, lo, hi), axis=-1)
    if gap.max() > limit:
        raise SimulationError(
            f"cloth simulation diverged at {where}: a vertex is {gap.max():.1f} m from the body"
        )


def _frame_name(k: int, n_settle: int, n_pre: int) -> str:
    if k < n_settle:
        return f"settle frame {k}"
    if k < n_pre:
        return f"blend frame {k - n_settle}"
    return f"motion frame {k - n_pre}"


def simulate(
    avatar: Avatar,
    template: GarmentTemplate,
    motion: Motion,
    config: ClothConfig | None = None,
    progress: Callable[[int, int], None] | None = None,
    resume: str | Path | None = None,
    *,
    resume_every: int = 50,
) -> SimResult:
    """Simulate a garment on the avatar through a motion.

    Args:
        avatar: the :class:`~loosefit.body.avatar.Avatar` the motion drives.
        template: the garment in the avatar's rest frame (root joint at the origin),
            e.g. from :func:`~loosefit.fitting.place.fit_skirt`.
        motion: T frames on the avatar's skeleton.
        config: the physics (default :class:`ClothConfig`).
        progress: called as ``progress(done, total)`` after every simulated frame.
        resume: a ``.npz`` file where the run saves its state (atomically, every
            ``resume_every`` frames) and from which a killed run of the same body
            motion, garment and configuration continues; deleted when the run
            ends. A file of another run is ignored and overwritten.
        resume_every: frames between saves.

    Returns:
        A :class:`SimResult` whose ``garment_vertices`` (T, V, 3) are in the world
        frame, frame ``t`` matching motion frame ``t``.

    Raises:
        LoosefitInputError: a template without waistband, a motion on other joints.
        SimulationError: NaN or a vertex more than ``config.max_distance`` from the body.
    """
    return simulate_batch(
        avatar, template, [motion], config, progress, resume, resume_every=resume_every
    )[0]


def simulate_batch(
    avatar: Avatar,
    template: GarmentTemplate,
    motions: list[Motion],
    config: ClothConfig | None = None,
    progress: Callable[[int, int], None] | None = None,
    resume: str | Path | None = None,
    *,
    resume_every: int = 50,
    seeds: list[int] | None = None,
    drape: np.ndarray | None = None,
) -> list[SimResult]:
    """Simulate a garment through several motions at once, each clip a world of one model.

    What :func:`simulate` does for one clip, for ``K`` clips stepped together (on a GPU,
    K clips cost little more than one). Every frame gets the substeps the most
    demanding clip needs then (:func:`~loosefit.sim.timeline.substep_schedule`, the
    maximum over the clips), so a clip may get more substeps than it would alone; a clip
    that ends before the longest holds its last pose until the batch ends. The motions
    must share a frame rate. Timings are the batch's, shared evenly among its clips
    (``seconds_per_frame`` is the batch's seconds per frame divided by K).

    Args:
        avatar, template, config, resume, resume_every: as :func:`simulate`.
        motions: K motions on the avatar's skeleton, all at one frame rate.
        progress: called as ``progress(done, total)`` after every batch frame.
        seeds: (K,) each clip's jitter seed (default: ``config.seed`` for all).
        drape: with ``config.settle_once``: (V, 3) the garment settled on the rest pose
            (:func:`settle`, in the rest pose's root frame) that every clip starts from,
            placed where its motion starts; settled here once for the batch when not given.
            Ignored otherwise.

    Returns:
        K :class:`SimResult`, one per motion, in order.

    Raises:
        LoosefitInputError: no motion, motions at different frame rates, a template
            without waistband, a motion on other joints.
        SimulationError: NaN or a vertex too far from the body in any clip (the message
            names the clip).
    """
    config = config or ClothConfig()
    fps = _check_batch(avatar, template, motions)
    K = len(motions)
    start = _batch_start(avatar, template, config, fps, drape)

    # 1. Each body over its whole timeline: settle (unless settled once), blend, motion.
    needs_parts = config.flatten_overlaps or config.release_depth is not None
    parts = collider_parts(avatar, config) if needs_parts else None  # once for all clips
    line_config = config if start is None else replace(config, settle_seconds=0.0)
    lines = [timeline(avatar, motion, line_config, parts) for motion in motions]
    bodies, colliders = [t.body for t in lines], [t.collider for t in lines]
    n_pre, n_settle = lines[0].n_pre, lines[0].n_settle
    body_faces, limb_faces, meshes = collider_meshes(avatar, config)
    totals = [len(b) - 1 for b in bodies]  # frames each clip steps
    total = max(totals)

    # 2. The simulator, with contact culling widened to the whole motions.
    t0 = time.perf_counter()
    sim = _batch_simulator(
        template, lines, body_faces, limb_faces, config, fps, seeds=seeds, start=start
    )
    t_build = time.perf_counter() - t0
    schedule = _batch_schedule(sim, colliders, totals, body_faces, config)

    def body_at(k: int) -> np.ndarray:
        """(Vb, 3) or (K, Vb, 3): each clip's body at timeline frame k (its last once over)."""
        at = np.stack([b[min(k, len(b) - 1)] for b in colliders])
        return at if K > 1 else at[0]

    # 3. Go on from a killed run's resume file, if there is one of this run.
    rec = Recording(
        outs=[np.empty((m.num_frames, template.num_vertices, 3), np.float32) for m in motions],
        settled=sim.positions.reshape(K, -1, 3).copy(),
        released=[np.zeros(len(b), np.int64) for b in bodies],
        releases=_fresh_releases(config, parts, meshes, colliders, template.num_vertices),
    )
    first, t_before = 0, 0.0
    resume = Path(resume) if resume is not None else None
    key = batch_key(bodies, template, config, seeds) if resume is not None else ""
    saved = read_resume(resume, key, total) if resume is not None else None
    if saved is not None:
        saved, rec.released = resumed_release(
            saved, config, colliders, rec.releases, n_pre, 1.0 / fps, released=rec.released
        )
        if saved is None:
            rec.releases = _fresh_releases(config, parts, meshes, colliders, template.num_vertices)
    if saved is not None:
        first, t_before, rec.settled = _restore(saved, sim, rec.outs, n_pre)

    # 4. Step through the timeline; record from the motions' first frame on.
    t0 = time.perf_counter()
    for k in range(first, total):
        if resume is not None and k > first and k % resume_every == 0:
            q, qd = sim.get_state()
            seconds = t_before + time.perf_counter() - t0
            depth = config.release_depth
            save_run(resume, key, k, q, qd, rec, n_pre=n_pre, release_depth=depth, seconds=seconds)
        settling = k + 1 < n_settle
        damping = config.settle_damping if settling else None
        sim.step_frame(body_at(k), body_at(k + 1), damping, substeps=int(schedule[k]))
        if rec.releases is not None and k + 1 >= n_pre:  # in the motion's frames
            _release_trapped(sim, rec.releases, colliders, totals, rec.released, k, fps=fps)
        _record_frame(sim.positions.reshape(K, -1, 3), k, rec, lines, motions, config)
        if progress is not None:
            progress(k + 1, total)
    t_sim = t_before + time.perf_counter() - t0
    if resume is not None:
        resume.unlink(missing_ok=True)

    timing = _BatchTiming(t_build, t_sim, total, first, schedule)
    faces = meshes[0] if len(meshes) == 1 else meshes  # what the quality is measured against
    return [
        _clip_result(config, template, motion, line, rec, c, measured_faces=faces, timing=timing)
        for c, (motion, line) in enumerate(zip(motions, lines, strict=True))
    ]


def _check_batch(avatar: Avatar, template: GarmentTemplate, motions: list[Motion]) -> float:
    """The batch's frame rate, once its motions and template are checked."""
    if not motions:
        raise LoosefitInputError("simulate_batch", "motions", "at least one motion", "none")
    fps = float(motions[0].fps)
    for m in motions:
        avatar.check_motion(m)
        if abs(float(m.fps) - fps) > 1e-9:
            raise LoosefitInputError(f"motion '{m.name}'", "fps", f"{fps} (the batch's)", m.fps)
    _check_template(template)
    return fps


def _batch_start(
    avatar: Avatar, template: GarmentTemplate, config: ClothConfig, fps: float, drape
) -> np.ndarray | None:
    """(V, 3) the drape every clip of a batch starts from with ``config.settle_once``: the
    one given, else settled here; None without it (the clips settle on their own)."""
    if not config.settle_once:
        return None
    start = _check_drape(template, drape) if drape is not None else None
    if start is None:
        start = settle(avatar, template, config, fps)
    return start


def _check_drape(template: GarmentTemplate, drape: np.ndarray) -> np.ndarray:
    """(V, 3) float64 ``drape`` checked against the template."""
    drape = np.asarray(drape)
    V = template.num_vertices
    if drape.shape != (V, 3) or not np.isfinite(drape).all():
        raise LoosefitInputError(
            "simulate_batch", "drape", f"({V}, 3) finite numbers", f"shape {drape.shape}"
        )
    return drape.astype(np.float64)


def _batch_simulator(
    template: GarmentTemplate,
    lines: list[Timeline],
    body_faces: np.ndarray,
    limb_faces: np.ndarray | None,
    config: ClothConfig,
    fps: float,
    *,
    seeds: list[int] | None,
    start: np.ndarray | None = None,
) -> ClothSimulator:
    """The simulator of a batch's clips (one world each, a lone clip unbatched), the garment
    (or the settled drape ``start``, root frame) placed on each clip's root in its first
    frame, contact culling over every body."""
    K = len(lines)
    shape = template.vertices if start is None else start
    garments = [
        shape.astype(np.float64) @ t.root_pose[:3, :3].T + t.root_pose[:3, 3] for t in lines
    ]
    rest = template.rest_vertices
    if start is not None and rest is None:  # the drape is where it starts, not its rest shape
        rest = template.vertices
    bodies = [t.body for t in lines]
    lower = np.min([b.min((0, 1)) for b in bodies], 0) - 2.0
    upper = np.max([b.max((0, 1)) for b in bodies], 0) + 2.0
    start_bodies = np.stack([t.collider[0] for t in lines])
    return ClothSimulator(
        np.stack(garments) if K > 1 else garments[0],
        template.faces,
        template.waist,
        start_bodies if K > 1 else start_bodies[0],
        body_faces,
        config,
        frame_dt=1.0 / fps,
        bounds=(lower, upper),
        loop=attached_loop(template),
        seeds=seeds,
        limb_faces=limb_faces,
        rest_vertices=rest,
    )


def _batch_schedule(
    sim: ClothSimulator,
    colliders: list[np.ndarray],
    totals: list[int],
    body_faces: np.ndarray,
    config: ClothConfig,
) -> np.ndarray:
    """(max(totals),) int64 substeps of each batch frame: the most any clip needs then."""
    schedule = np.full(max(totals), config.substeps, np.int64)
    if config.max_substeps > config.substeps:
        for glue, body, n in zip(sim.glues, colliders, totals, strict=True):
            waist = np.stack([glued_points(glue, b, body_faces) for b in body])  # (P + T, W, 3)
            own = substep_schedule(
                waist,
                config.substeps,
                config.max_substeps,
                config.substep_waist_move,
                body_moves=None if config.substep_body_move is None else body_moves(body, waist),
                max_body_move=config.substep_body_move,
            )
            schedule[:n] = np.maximum(schedule[:n], own)
    return schedule


def _fresh_releases(
    config: ClothConfig,
    parts: BodyParts | None,
    meshes: tuple[np.ndarray, ...],
    colliders: list[np.ndarray],
    num_vertices: int,
) -> list[TrappedRelease] | None:
    """Each clip's release of trapped cloth, anchored nowhere yet (None: the release is off)."""
    if config.release_depth is None:
        return None
    where = release_parts(parts)
    return [
        TrappedRelease(
            c[0], meshes, where, num_vertices, config.release_depth, config.body_contact_distance
        )
        for c in colliders
    ]


def _record_frame(
    positions: np.ndarray,
    k: int,
    rec: Recording,
    lines: list[Timeline],
    motions: list[Motion],
    config: ClothConfig,
) -> None:
    """After timeline frame ``k``: each running clip's cloth ``positions`` (K, V, 3) checked
    (:func:`_guard`) and recorded where the motion has begun, the drape kept at the end of
    the settle phase."""
    K = len(lines)
    n_settle, n_pre = lines[0].n_settle, lines[0].n_pre
    for c, line in enumerate(lines):
        if k >= len(line.body) - 1:
            continue  # this clip is over: it holds its last pose
        where = _frame_name(k + 1, n_settle, n_pre)
        where = where if K == 1 else f"{where} of clip '{motions[c].name}'"
        _guard(positions[c], line.body[k + 1], config.max_distance, where)
        if k + 1 >= n_pre:
            rec.outs[c][k + 1 - n_pre] = positions[c]
    if k + 1 == n_settle - 1:
        rec.settled = positions.copy()


def _restore(
    saved: dict, sim: ClothSimulator, outs: list[np.ndarray], n_pre: int
) -> tuple[int, float, np.ndarray]:
    """Take a resume file's state: the simulator's, and the frames it recorded into ``outs``.

    Returns:
        The timeline frame it goes on from, the seconds simulated before, and the (K, V, 3)
        settled garments.
    """
    K, V = len(outs), sim.num_vertices
    shape = (K, V, 3) if K > 1 else (V, 3)
    sim.set_state(saved["positions"].reshape(shape), saved["velocities"].reshape(shape))
    first = int(saved["frame"])
    recorded = max(first - n_pre + 1, 0)
    for c, out in enumerate(outs):
        n = min(recorded, len(out))
        out[:n] = saved[f"garment_{c}" if K > 1 else "garment"][:n]
    return first, float(saved["seconds"]), saved["settled"].reshape(K, -1, 3)


def _release_trapped(
    sim: ClothSimulator,
    releases: list[TrappedRelease],
    colliders: list[np.ndarray],
    totals: list[int],
    released: list[np.ndarray],
    k: int,
    *,
    fps: float,
) -> None:
    """After timeline frame ``k``: each running clip's trapped cloth put back on the skin
    (counted in ``released``), the simulator's state updated where any was."""
    K = len(releases)
    q, qd = (a.reshape(K, -1, 3) for a in sim.get_state())
    count = 0
    for c, body in enumerate(colliders):
        if k >= totals[c]:
            continue
        q[c], qd[c], n = releases[c].step(q[c], qd[c], body[k + 1], body[k], 1.0 / fps)
        released[c][k + 1] = n
        count += n
    if count:
        sim.set_state(q if K > 1 else q[0], qd if K > 1 else qd[0])


@dataclass
class _BatchTiming:
    """How a batch ran: seconds building and simulating, frames, the substeps per frame."""

    build_seconds: float
    simulate_seconds: float
    batch_frames: int  # the longest clip's timeline frames
    resumed_frame: int  # the timeline frame a killed run went on from (0: none)
    schedule: np.ndarray  # (batch_frames,) substeps per frame


def _clip_result(
    config: ClothConfig,
    template: GarmentTemplate,
    motion: Motion,
    line: Timeline,
    rec: Recording,
    c: int,
    *,
    measured_faces: np.ndarray | tuple[np.ndarray, ...],
    timing: _BatchTiming,
) -> SimResult:
    """One clip's :class:`SimResult`: its frames, quality, and its share of the batch's cost."""
    body, n_pre, K = line.body, line.n_pre, len(rec.outs)
    garment, released = rec.outs[c], rec.released[c]
    n = len(body) - 1
    schedule = timing.schedule
    stats = {
        "vertices": template.num_vertices,
        "body_vertices": int(body.shape[1]),
        "frames_simulated": n,
        "substeps_mean": float(schedule[:n].mean()) if n else float(config.substeps),
        "substeps_max": int(schedule[:n].max()) if n else config.substeps,
        "build_seconds": timing.build_seconds / K,
        "simulate_seconds": timing.simulate_seconds / K,
        "batch": K,
        "batch_frames": timing.batch_frames,
        "resumed_frame": timing.resumed_frame,
        # the pose folding into itself: frames whose collider was pressed, the deepest
        # limb vertex inside the rest of the body (m)
        "overlap_frames": int((line.pressed[n_pre:] > 0).sum()),
        # cloth put back on the skin from deeper than release_depth: frames, vertices
        "released_frames": int((released[n_pre:] > 0).sum()),
        "released_vertices": int(released[n_pre:].sum()),
        "overlap_depth_max": float(line.overlap[n_pre:].max(initial=0.0)),
        "config": asdict(config),
    }
    return SimResult(
        garment_vertices=garment,
        faces=template.faces.copy(),
        fps=motion.fps,
        seconds_per_frame=timing.simulate_seconds / K / max(timing.batch_frames, 1),
        preroll_frames=n_pre,
        settled_vertices=rec.settled[c],
        quality=quality(garment, template, body[n_pre:], measured_faces, motion.fps),
        stats=stats,
    )


def settle(
    avatar: Avatar,
    template: GarmentTemplate,
    config: ClothConfig | None = None,
    fps: float = 30.0,
    progress: Callable[[int, int], None] | None = None,
) -> np.ndarray:
    """The garment draped on the rest pose: the settle phase of :func:`simulate` on its own.

    This is where every simulated clip starts from (the same drape, moved to where
    the motion starts), and so where a learned rollout starts from.

    Args:
        avatar: the body.
        template: the garment in the avatar's rest frame.
        config: the physics (``settle_seconds``, ``settle_damping``, ...).
        fps: the frame rate of the clips (the settle phase steps whole frames).
        progress: called as ``progress(done, total)`` after every frame of the drape.

    Returns:
        (V, 3) float32 vertices in the rest pose's root frame (root joint at the
        origin, facing -Y).
    """
    config = config or ClothConfig()
    _check_template(template)
    J = len(avatar.joint_names)
    rest = torch.eye(3).expand(1, J, 3, 3).contiguous()
    root = torch.tensor([[0.0, 0.0, avatar.floor_height]])
    with torch.no_grad():
        body = avatar.pose(rest, root).vertices[0].detach().to("cpu", torch.float32).numpy()
    garment = template.vertices.astype(np.float64) + root.numpy()[0]
    sim = ClothSimulator(
        garment,
        template.faces,
        template.waist,
        body,
        avatar.collider_faces(arms=config.arm_collision).cpu().numpy(),
        config,
        frame_dt=1.0 / fps,
        bounds=(body.min(0) - 2.0, body.max(0) + 2.0),
        loop=attached_loop(template),
        limb_faces=limb_collider_faces(avatar, config),
        rest_vertices=template.rest_vertices,
    )
    n_settle = int(round(config.settle_seconds * fps)) + 1
    for k in range(n_settle - 1):
        sim.step_frame(body, body, config.settle_damping)
        _guard(sim.positions, body, config.max_distance, f"settle frame {k + 1}")
        if progress is not None:
            progress(k + 1, n_settle - 1)
    return (sim.positions - root.numpy()).astype(np.float32)
