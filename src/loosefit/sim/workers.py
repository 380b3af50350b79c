"""The workers of a data set run: a process that builds the body and the garment once,
then simulates units of work (a clip, or a batch of clips) and writes them.

A :class:`Worker` holds what every unit needs; it is built in the process that runs the
units and passed to them, so nothing is kept between runs in module state:

* in the driver's own process (``--workers 1``): :meth:`Worker.build`, then
  :meth:`Worker.run` for each unit;
* in a pool of processes (``--workers N``): :func:`serve` in each, which builds one
  worker and runs the units it takes from a queue until it takes ``None``;
* as a Ray task (:mod:`loosefit.sim.cluster`): :func:`run_clips`, which builds the
  worker for its unit.

Batched clips (a GPU's units) have their motions prepared first, every clip in parallel
(:func:`prepare_motions`): the pose correction is CPU work of up to a tenth of a second a
frame, which a worker running a batch would otherwise do for each of its clips in turn
before the batch's first frame.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from loosefit.data.format import write_sequence
from loosefit.errors import LoosefitInputError
from loosefit.sequence import GarmentSequence
from loosefit.sim.dataset_config import DatasetConfig, make_garment
from loosefit.sim.driver import SimulationError, simulate_batch
from loosefit.sim.jobs import Job, job_motion, limb_parts, unit_name
from loosefit.sim.manifest import clip_entry

if TYPE_CHECKING:
    from loosefit.body.avatar import Avatar
    from loosefit.body.regions import BodyParts
    from loosefit.types import GarmentTemplate


def exit_with_parent(poll_seconds: float = 2.0) -> None:
    """In a worker process: exit when the parent dies (a killed run leaves no orphans)."""
    import threading

    parent = os.getppid()

    def watch() -> None:
        while True:
            time.sleep(poll_seconds)
            if os.getppid() != parent:
                os._exit(1)

    threading.Thread(target=watch, daemon=True).start()


@contextlib.contextmanager
def one_torch_thread():
    """Run the block on one torch thread, as every simulation worker does, then give the
    caller back its own count. The avatar's rest shape, and so the garment fitted to it,
    differs in a float's last bit between thread counts (torch's reductions split the work
    differently): built on one thread, the data set's ``template.npz`` is the garment its
    clips were simulated with, whatever the caller's threads."""
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(threads)


@dataclass
class Worker:
    """What a worker process builds once for a data set, and runs its units of work with."""

    config: DatasetConfig  # the data set's configuration
    avatar: Avatar  # the body, with the data set's shape
    # the data set's garment, fitted to the avatar (None: a worker that only prepares motions)
    template: GarmentTemplate | None
    progress: object = None  # anything with put((name, frame, total)), or None
    # the body parts the pose correction tests (jobs.limb_parts), built for the first clip
    parts: BodyParts | None = None

    @classmethod
    def build(cls, config: DatasetConfig, progress=None, garment: bool = True) -> Worker:
        """Build the avatar and the garment (``garment`` False: none, for a worker that only
        prepares motions) on one torch thread (as every worker runs)."""
        import torch

        from loosefit.body.avatar import Avatar, AvatarConfig

        torch.set_num_threads(1)
        avatar = Avatar(AvatarConfig(shape=dict(config.shape)))
        template = make_garment(config.garment, avatar) if garment else None
        return cls(config, avatar, template, progress)

    def motion(self, job: Job):
        """The motion ``job`` simulates (:func:`~loosefit.sim.jobs.job_motion`)."""
        if self.parts is None and self.config.unfold.enabled:
            self.parts = limb_parts(self.config, self.avatar)
        return job_motion(self.config, job, self.avatar, parts=self.parts)

    def run(
        self,
        jobs: list[Job],
        out_dir: str,
        resume_every: int = 50,
        motions: list | None = None,
    ) -> list[dict]:
        """Simulate clips together (one clip, or a batch: :func:`simulate_batch`) and write
        them; returns their manifest entries. The run saves its state in ``out_dir/resume``
        every ``resume_every`` frames and goes on from there when run again after a kill.
        A batch in which one clip diverges is run again clip by clip, so that only that clip
        is flagged. ``motions``: the jobs' motions as :meth:`motion` makes them, prepared
        already (:func:`prepare_motions`); None: made here."""
        config, avatar, template, q = self.config, self.avatar, self.template, self.progress
        if motions is None:
            motions = [self.motion(job) for job in jobs]
        elif len(motions) != len(jobs):
            raise ValueError(f"motions: expected {len(jobs)} (one a job), found {len(motions)}")
        name = unit_name(jobs)
        t0 = time.perf_counter()

        def progress(done: int, total: int) -> None:
            if q is not None:
                q.put((name, done, total))

        resume_dir = Path(out_dir) / "resume"
        resume_dir.mkdir(exist_ok=True)
        drape = None  # with settle_once: the data set's, settled once before any clip
        if config.cloth.settle_once and (Path(out_dir) / "rest_drape.npy").is_file():
            drape = np.load(Path(out_dir) / "rest_drape.npy", allow_pickle=False)
        try:
            results = simulate_batch(
                avatar,
                template,
                motions,
                config.cloth,
                progress=progress,
                resume=resume_dir / f"{name}.npz",
                resume_every=resume_every,
                seeds=[job.jitter_seed for job in jobs],
                drape=drape,
            )
        except SimulationError as exc:
            if len(jobs) > 1:
                return [
                    e
                    for job, motion in zip(jobs, motions, strict=True)
                    for e in self.run([job], out_dir, resume_every, [motion])
                ]
            elapsed = time.perf_counter() - t0
            return [clip_entry(config, jobs[0], motions[0], None, elapsed, str(exc))]
        for job, motion, result in zip(jobs, motions, results, strict=True):
            write_sequence(
                Path(out_dir) / "sequences" / f"{job.name}.npz",
                GarmentSequence(
                    dataclasses.replace(motion, name=job.name),
                    template,
                    result.garment_vertices,
                    {"rig": avatar.config.rig, "shape": dict(avatar.shape)},
                    "newton-vbd",
                ),
            )
        return [clip_entry(config, j, m, r) for j, m, r in zip(jobs, motions, results, strict=True)]


def serve(config: DatasetConfig, units, results, progress) -> None:
    """A pool process's loop: exit with the parent, build one :class:`Worker`, then run
    each ``(index, jobs, out_dir, resume_every, motions)`` taken from ``units`` until
    ``None`` (``motions``: prepared, or None), putting ``(index, entries)`` in ``results``.
    An error ends the loop and is raised to whoever waits on this process's task."""
    exit_with_parent()
    worker = Worker.build(config, progress)
    for index, jobs, out_dir, resume_every, motions in iter(units.get, None):
        results.put((index, worker.run(jobs, out_dir, resume_every, motions)))


def _serve_motions(config: DatasetConfig, jobs, results) -> None:
    """A pool process's loop of :func:`prepare_motions`: each job index taken from ``jobs``
    until ``None``, its motion put in ``results`` as ``(index, motion)``."""
    exit_with_parent()
    worker = Worker.build(config, garment=False)
    for index, job in iter(jobs.get, None):
        results.put((index, worker.motion(job)))


def prepare_motions(
    config: DatasetConfig,
    jobs: list[Job],
    processes: int,
    on_done: Callable[[Job, object], None] | None = None,
) -> list:
    """The motions ``jobs`` simulate, as :meth:`Worker.motion` makes them (loaded at the data
    set's frame rate, pose-corrected), the same to the bit, made in ``processes`` processes
    at once (one: in this one), in the order of ``jobs`` (put the longest first: the last to
    start should not be the longest to finish).

    Args:
        on_done: called with each job and its motion as it is ready (a progress bar).

    Returns:
        The motions, in the order of ``jobs``.

    Raises:
        whatever preparing a motion raised (a missing file, a motion on other joints).
    """
    if not isinstance(processes, int) or processes < 1:
        raise LoosefitInputError("prepare_motions", "processes", "an integer >= 1", repr(processes))
    processes = min(processes, len(jobs))
    motions: list = [None] * len(jobs)
    if processes <= 1:
        with one_torch_thread():  # as a worker process runs: the caller's threads given back
            worker = Worker.build(config, garment=False) if jobs else None
            for index, job in enumerate(jobs):
                motions[index] = worker.motion(job)
                if on_done is not None:
                    on_done(job, motions[index])
        return motions

    def take(index: int, motion) -> None:
        motions[index] = motion
        if on_done is not None:
            on_done(jobs[index], motion)

    run_in_processes(_serve_motions, (config,), [(job,) for job in jobs], processes, take)
    return motions


def run_in_processes(
    target: Callable,
    args: tuple,
    tasks: list[tuple],
    processes: int,
    on_result: Callable[[int, object], None],
    on_wait: Callable[[object], None] | None = None,
) -> None:
    """Run ``target(*args, todo, done, side)`` in ``processes`` spawned processes (spawned:
    a parent with CUDA open cannot fork), each a loop that takes ``(index, *task)`` from
    ``todo`` until ``None`` and puts ``(index, result)`` in ``done``; ``on_result(index,
    result)`` is called here as each finishes. ``side`` is one more queue of the same
    manager (a progress queue), handed to ``on_wait`` whenever this loop waits and at the
    end (None: the processes do not get one).

    Raises:
        whatever a process raised (its error, or the pool broken by a process that died);
        RuntimeError if they all stopped with tasks left.
    """
    import multiprocessing as mp
    import queue
    from concurrent.futures import ProcessPoolExecutor

    ctx = mp.get_context("spawn")
    with ctx.Manager() as manager:
        todo, done = manager.Queue(), manager.Queue()
        side = (manager.Queue(),) if on_wait is not None else ()
        for index, task in enumerate(tasks):
            todo.put((index, *task))
        for _ in range(processes):
            todo.put(None)  # one stop for each process
        with ProcessPoolExecutor(max_workers=processes, mp_context=ctx) as pool:
            running = [pool.submit(target, *args, todo, done, *side) for _ in range(processes)]
            left = len(tasks)
            while left:
                if on_wait is not None:
                    on_wait(*side)
                try:
                    index, result = done.get(timeout=0.2)
                except queue.Empty:
                    for f in running:
                        if f.done():
                            f.result()  # a process's error, raised here
                    if all(f.done() for f in running):
                        raise RuntimeError(
                            f"the processes stopped with {left} tasks left"
                        ) from None
                    continue
                if on_wait is not None:
                    on_wait(*side)
                on_result(index, result)
                left -= 1
            if on_wait is not None:
                on_wait(*side)


def run_clips(
    config: DatasetConfig,
    jobs: list[Job],
    out_dir: str,
    resume_every: int = 50,
    progress_queue=None,
) -> list[dict]:
    """Simulate and write one unit of work in any process (:meth:`Worker.run`, with a
    worker built for it): what a Ray task runs (:mod:`loosefit.sim.cluster`).

    Args:
        progress_queue: anything with ``put((name, frame, total))``, or None.
    """
    return Worker.build(config, progress_queue).run(jobs, out_dir, resume_every)
