"""The simulator's runs measured: timed, profiled phase by phase, and cached.

* :func:`time_simulation`: seconds a frame of a motion simulated with a model's garment;
  :func:`model_cloth`: the cloth configuration the model's training data was simulated with;
* :class:`Timer`, :func:`instrument`, :func:`profiled_run`: where a simulated frame's time
  goes (each phase of the loop over frames, each warp kernel, what a clip pays once);
* :func:`parse_candidate`, :func:`candidate_config`, :func:`simulate_run`: a cloth
  configuration changed from a preset's (``NAME:KEY=VALUE,...``), one clip simulated with it
  and cached.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import time
from collections import defaultdict
from pathlib import Path

import numpy as np
import torch


def time_simulation(model, avatar, motion, device: str, cloth: dict) -> dict:
    """Seconds a frame (wall and this process's CPU) of ``motion`` simulated on ``device``
    with the model's garment and the cloth configuration ``cloth`` (a dict of
    :class:`~loosefit.sim.cloth_config.ClothConfig`'s fields); the settling before the
    motion's first frame left out."""
    from loosefit.sim.cloth_config import ClothConfig
    from loosefit.sim.driver import simulate

    cloth = dict(cloth)
    cloth["device"] = device
    marks = {}

    def progress(done, total):
        if done == total - motion.num_frames:
            marks["start"], marks["cpu"] = time.perf_counter(), time.process_time()

    simulate(avatar, model.template, motion, ClothConfig(**cloth), progress=progress)
    s = (time.perf_counter() - marks["start"]) / motion.num_frames
    cpu = (time.process_time() - marks["cpu"]) / motion.num_frames
    return {"device": device, "seconds_per_frame": s, "cpu_seconds_per_frame": cpu}


def model_cloth(model, dataset: str | None) -> dict:
    """The cloth configuration of the model's training data (its checkpoint's, or a dataset's)."""
    if dataset:
        return json.loads((Path(dataset) / "manifest.json").read_text())["config"]["cloth"]
    data = torch.load(model.path, map_location="cpu", weights_only=False)
    if not data.get("cloth"):
        raise SystemExit(f"{model.path} records no cloth configuration; pass --cloth-from DATASET")
    return data["cloth"]


class Timer:
    """Inclusive and exclusive seconds of nested labelled calls."""

    def __init__(self) -> None:
        self.total: dict[str, float] = defaultdict(float)
        self.self_: dict[str, float] = defaultdict(float)
        self.calls: dict[str, int] = defaultdict(int)
        self.stack: list[list] = []  # [label, start, child seconds]
        self._undo: list[tuple] = []  # (owner, attribute, what it was), in order

    def replace(self, owner, attr: str, new) -> None:
        """Set ``owner.attr`` to ``new`` until :meth:`restore`."""
        self._undo.append((owner, attr, getattr(owner, attr)))
        setattr(owner, attr, new)

    def wrap(self, owner, attr: str, label: str) -> None:
        """Time every call of ``owner.attr`` as ``label`` until :meth:`restore`."""
        inner = getattr(owner, attr)
        timer = self

        def timed(*args, **kwargs):
            timer.stack.append([label, time.perf_counter(), 0.0])
            try:
                return inner(*args, **kwargs)
            finally:
                lab, t0, child = timer.stack.pop()
                dt = time.perf_counter() - t0
                timer.total[lab] += dt
                timer.self_[lab] += dt - child
                timer.calls[lab] += 1
                if timer.stack:
                    timer.stack[-1][2] += dt

        self.replace(owner, attr, timed)

    def restore(self) -> None:
        """Put back every attribute :meth:`replace` or :meth:`wrap` set."""
        for owner, attr, inner in reversed(self._undo):
            setattr(owner, attr, inner)
        self._undo.clear()


def kernel_name(kernel) -> str:
    """A warp kernel's name."""
    return getattr(kernel, "key", None) or getattr(kernel, "__name__", str(kernel))


# what runs once for a clip (seconds a clip), not in the loop over its frames
ONCE = {
    "collider_parts": "body parts (pose correction, release)",
    "timeline": "body timeline (anny posing the clip)",
    "collider_meshes": "collider meshes",
    "_batch_simulator": "building the simulator",
    "_batch_schedule": "substep schedule",
    "_clip_result": "the clip's quality figures",
}


def instrument(timer: Timer, kernels: Timer) -> None:
    """Wrap the simulator's phases (``timer``) and every warp launch of the loop over frames
    (``kernels``)."""
    import newton
    import warp as wp
    from newton.solvers import SolverVBD

    import loosefit.sim.driver as driver
    import loosefit.sim.stepper as stepper

    for attr, label in ONCE.items():
        timer.wrap(driver, attr, label)
    timer.wrap(stepper.ClothSimulator, "step_frame", "frame: body upload, the rest")
    timer.wrap(SolverVBD, "rebuild_bvh", "self-contact BVH rebuild (once a frame)")
    timer.wrap(stepper.ClothSimulator, "_pose_body", "body posed and refitted (each substep)")
    timer.wrap(stepper.ClothSimulator, "_pin_waist", "waistband pinned")
    timer.wrap(newton.CollisionPipeline, "collide", "body contact detection")
    timer.wrap(SolverVBD, "step", "solver: the rest of a step")
    timer.wrap(SolverVBD, "_initialize_particles", "solver: forward step")
    timer.wrap(SolverVBD, "_mid_step_detection", "solver: self-contact detection")
    timer.wrap(SolverVBD, "_solve_particle_iteration", "solver: VBD iterations")
    timer.wrap(driver, "_release_trapped", "release of trapped cloth")
    timer.wrap(driver, "_record_frame", "frame recorded and checked")

    launch = wp.launch
    once = set(ONCE.values())

    def timed_launch(kernel, *args, **kwargs):
        if not timer.stack or timer.stack[0][0] in once:  # only the loop over frames
            return launch(kernel, *args, **kwargs)
        t0 = time.perf_counter()
        try:
            return launch(kernel, *args, **kwargs)
        finally:
            name = kernel_name(kwargs.get("kernel", kernel))
            kernels.total[name] += time.perf_counter() - t0
            kernels.calls[name] += 1

    kernels.replace(wp, "launch", timed_launch)


def profiled_run(avatar, template, motion, cloth, seeds=None):
    """``motion`` simulated once with every phase and kernel timed (graph capture off),
    after a short run outside the timing (warp compiles every kernel once per process).

    Returns:
        The clip's result, the phases' :class:`Timer`, the kernels' and the wall seconds.
    """
    import loosefit.sim.driver as driver

    short = dataclasses.replace(cloth, settle_seconds=0.0, blend_seconds=0.0)
    driver.simulate_batch(avatar, template, [motion.slice(0, 2)], short, seeds=seeds)
    timer, kernels = Timer(), Timer()
    instrument(timer, kernels)
    t0 = time.perf_counter()
    try:
        (result,) = driver.simulate_batch(
            avatar, template, [motion], dataclasses.replace(cloth, capture=False), seeds=seeds
        )
    finally:
        timer.restore()
        kernels.restore()
    return result, timer, kernels, time.perf_counter() - t0


def parse_candidate(spec: str) -> tuple[str, dict]:
    """``NAME:KEY=VALUE,KEY=VALUE`` (values as JSON) to (name, the cloth's changes)."""
    name, _, items = spec.partition(":")
    changes = {}
    for item in filter(None, items.split(",")):
        key, _, value = item.partition("=")
        changes[key] = json.loads(value)
    return name, changes


def candidate_config(preset_name: str, changes: dict):
    """The preset ``preset_name``'s configuration with the cloth's fields ``changes`` set."""
    from loosefit.sim.presets import preset

    config = preset(preset_name)
    return dataclasses.replace(config, cloth=dataclasses.replace(config.cloth, **changes))


def run_key(clip: str, frames: int, seed_shift: int, changes: dict) -> str:
    """The name a run of :func:`simulate_run` is cached under."""
    text = json.dumps([clip, frames, seed_shift, sorted(changes.items())], default=str)
    return f"{clip}-{frames}-{hashlib.sha256(text.encode()).hexdigest()[:10]}"


def simulate_run(
    preset_name: str, clip: str, frames: int, seed_shift: int, changes: dict, cache: str
) -> dict:
    """One run, in a process of its own (one torch thread), cached in ``cache``."""
    path = Path(cache) / f"{run_key(clip, frames, seed_shift, changes)}.npz"
    if path.is_file():
        with np.load(path, allow_pickle=False) as z:
            return {"garment": z["garment"], **json.loads(str(z["record"]))}
    from loosefit.sim.driver import SimulationError, simulate_batch
    from loosefit.sim.jobs import plan_jobs
    from loosefit.sim.manifest import clip_entry
    from loosefit.sim.workers import Worker

    config = candidate_config(preset_name, changes)
    worker = Worker.build(config)
    job = {j.name: j for j in plan_jobs(config)}[clip]
    motion = worker.motion(job).slice(0, frames)
    seed = job.seed + seed_shift
    t0 = time.perf_counter()
    try:
        (result,) = simulate_batch(
            worker.avatar, worker.template, [motion], config.cloth, seeds=[seed]
        )
    except SimulationError as exc:
        return {"garment": None, "status": "flagged", "reason": str(exc), "seconds": 0.0}
    wall = time.perf_counter() - t0
    entry = clip_entry(config, dataclasses.replace(job, seed=seed), motion, result)
    record = {
        "status": entry["status"],
        "reason": entry.get("reason", ""),
        "seconds_per_frame": result.seconds_per_frame,
        "wall": wall,
        "frames_stepped": result.stats["frames_simulated"],
        "substeps_mean": result.stats["substeps_mean"],
        "quality": {
            k: float(v)
            for k, v in result.quality.items()
            if np.ndim(v) == 0 and isinstance(v, int | float | np.floating | np.integer)
        },
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".partial.npz")
    np.savez(tmp, garment=result.garment_vertices, record=json.dumps(record))
    tmp.replace(path)
    return {"garment": result.garment_vertices, **record}
