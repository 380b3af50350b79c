"""Making a dataset: many motions simulated with one garment, in parallel, resumably.

``generate(config, out_dir, workers)`` simulates every clip of a
:class:`~loosefit.sim.dataset_config.DatasetConfig`, writes each finished clip
atomically, keeps the manifest up to date after every clip, and on a rerun with the same
configuration skips what is done. Clips whose quality fails the thresholds (sinking into
the body, exploding, NaN) are flagged in the manifest and kept out of the split rather
than silently used.

Where the pieces live: the configuration (:mod:`~loosefit.sim.dataset_config`) and its
presets (:mod:`~loosefit.sim.presets`), the clips (:mod:`~loosefit.sim.jobs`), the
manifest and its migrations (:mod:`~loosefit.sim.manifest`), the processes that simulate
(:mod:`~loosefit.sim.workers`, or a Ray cluster: :mod:`~loosefit.sim.cluster`), and the
report (:mod:`~loosefit.sim.report`).
"""

from __future__ import annotations

import os
import queue
from collections.abc import Callable
from pathlib import Path

from tqdm import tqdm

from loosefit.data.format import write_json_atomic
from loosefit.errors import LoosefitInputError
from loosefit.sim.cluster import ClusterConfig, preflight, run_on_ray
from loosefit.sim.dataset_config import DatasetConfig, make_garment
from loosefit.sim.jobs import Job, job_motion, plan_jobs, unit_name
from loosefit.sim.manifest import adopt_clips, open_manifest, recheck_release, recheck_unfold
from loosefit.sim.report import summarize
from loosefit.sim.workers import (
    Worker,
    one_torch_thread,
    prepare_motions,
    run_in_processes,
    serve,
)

__all__ = ["generate"]


def generate(
    config: DatasetConfig,
    out_dir: str | Path,
    workers: int = 1,
    progress: bool = True,
    reuse: str | Path | None = None,
    batch: int = 1,
    *,
    resume_every: int = 50,
    cluster: ClusterConfig | None = None,
    prepare_workers: int | None = None,
) -> dict:
    """Simulate a dataset into ``out_dir`` (resuming a run of the same configuration).

    Args:
        config: what to simulate.
        out_dir: the dataset folder (new, empty, or holding the same configuration).
        workers: parallel simulations (one CPU core each on the CPU); with ``cluster``,
            the CPUs of a Ray instance it starts on this machine when it finds none.
        batch: clips simulated at once, each a world of one Newton model
            (:func:`~loosefit.sim.driver.simulate_batch`): for a GPU, where 16 clips
            cost little more than one. Clips of similar length go together (none shorter
            than half its batch's longest: a long clip goes alone).
        progress: show a progress bar over frames with rate and ETA.
        reuse: another dataset folder whose clips of the same simulation are
            taken rather than simulated again
            (:func:`~loosefit.sim.manifest.adopt_clips`).
        resume_every: frames between the saves of a clip's state in ``out_dir/resume``,
            from which a killed run goes on.
        cluster: run every unit of work as a task on this Ray cluster
            (:func:`loosefit.sim.cluster.run_on_ray`; ``out_dir`` on storage every node
            shares) instead of in processes of this machine; the data set is the same.
        prepare_workers: with ``batch`` > 1, the processes that prepare every clip's motion
            (loaded, pose-corrected: CPU work) before the batches are simulated; default:
            every CPU core. A clip alone is prepared by the worker that simulates it.

    Returns:
        The final manifest (also written to ``out_dir/manifest.json``).
    """
    _check_counts(batch=batch, resume_every=resume_every, prepare_workers=prepare_workers)
    if cluster is not None:  # no ray, or no cluster at the address: now, before any work
        preflight(cluster)
    out = Path(out_dir)
    jobs = plan_jobs(config)
    manifest = open_manifest(config, out)
    (out / "sequences").mkdir(parents=True, exist_ok=True)
    for stale in (out / "sequences").glob("*.partial.npz"):
        stale.unlink()  # left by a killed run: never a whole sequence

    # 1. The body and garment, and the clips this folder holds already.
    avatar, template = _body_and_garment(config, out, manifest)
    _take_what_is_done(
        config, jobs, manifest, out, avatar, template, reuse=reuse, progress=progress
    )

    # 2. The units of work left: clips alone, or batches of clips of similar length.
    done = {
        n
        for n, e in manifest["sequences"].items()
        if e.get("status") == "flagged" or (out / "sequences" / f"{n}.npz").is_file()
    }
    todo = [j for j in jobs if j.name not in done]
    if todo:  # (a finished data set made before the drape was recorded is left as it is)
        _rest_drape(config, out, avatar, template)
    groups, frames_of = _units(config, todo, avatar, batch)
    # longest first, so that no long clip starts last and runs alone
    by_length = sorted(groups, key=lambda g: -frames_of[unit_name(g)])
    prepared = None  # batches' motions, prepared on every core before the first batch
    if batch > 1 and cluster is None and any(len(g) > 1 for g in groups):
        processes = prepare_workers or os.cpu_count() or 1
        prepared = _prepare(config, by_length, processes, progress)
    bar = _Progress(frames_of, _frame_bar(config, frames_of, len(todo), batch, progress))

    def record(group: list[Job], entries: list[dict]) -> None:
        for job, entry in zip(group, entries, strict=True):
            manifest["sequences"][job.name] = entry
            if entry["status"] == "flagged":
                tqdm.write(f"flagged {job.name}: {entry['reason']}")
        write_json_atomic(out / "manifest.json", manifest)

    # 3. Simulate them.
    if cluster is not None:
        created = manifest.get("created", "")
        run_on_ray(
            cluster,
            config,
            by_length,
            str(out),
            resume_every,
            created,
            on_progress=bar.update,
            record=record,
            local_cpus=workers,
        )
    elif workers <= 1:
        with one_torch_thread():  # in this process: its thread count is the caller's again
            worker = Worker.build(config, _Direct(bar.update))
            for group in groups:
                motions = None if prepared is None else prepared[unit_name(group)]
                record(group, worker.run(group, str(out), resume_every, motions))
    else:
        _run_in_pool(
            config,
            by_length,
            str(out),
            resume_every,
            workers,
            bar.update,
            record=record,
            prepared=prepared,
        )
    bar.close()
    return _finish(jobs, manifest, out)


def _frame_bar(config: DatasetConfig, frames_of: dict[str, int], clips: int, batch: int, show):
    """The tqdm bar over the frames of every unit of work (``frames_of``, by unit name)."""
    return tqdm(
        total=sum(frames_of.values()),
        unit="frame",
        desc=f"simulate {config.preset} ({clips} clips"
        + (f", {batch} at once)" if batch > 1 else ")"),
        disable=not show,
        smoothing=0.05,
    )


def _check_counts(**counts: int | None) -> None:
    """Each of ``generate``'s counts an integer >= 1 (``prepare_workers`` may be None)."""
    for name, value in counts.items():
        if value is None and name == "prepare_workers":
            continue
        if not (isinstance(value, int) and not isinstance(value, bool) and value >= 1):
            expected = "an integer >= 1" + (" (or None)" if name == "prepare_workers" else "")
            raise LoosefitInputError("generate", name, expected, repr(value))


def _body_and_garment(config: DatasetConfig, out: Path, manifest: dict):
    """The avatar and the garment (built on one torch thread, as the workers build them),
    the garment's template saved in ``out`` and both noted in the manifest."""
    from loosefit.body.avatar import Avatar, AvatarConfig
    from loosefit.fitting.place import collider_arms

    with one_torch_thread():
        avatar = Avatar(AvatarConfig(shape=dict(config.shape)))
        template = make_garment(config.garment, avatar)
    if collider_arms(template) == "upper" and config.cloth.arm_collision is False:
        raise LoosefitInputError(
            "DatasetConfig",
            "cloth.arm_collision",
            "'upper' (or true) for a dress: its bodice reaches the arms",
            "false",
            hint="set cloth.arm_collision = 'upper'",
        )
    template.save(out / "template.npz")
    manifest["body"] = {
        "model": "anny",
        "rig": avatar.config.rig,
        "shape": avatar.shape,
        "floor_height": avatar.floor_height,
    }
    manifest["garment"] = {"name": template.name, "num_vertices": template.num_vertices}
    write_json_atomic(out / "manifest.json", manifest)
    return avatar, template


def _rest_drape(config: DatasetConfig, out: Path, avatar, template) -> None:
    """Settle the garment on the rest pose once (``out/rest_drape.npy``, written atomically):
    where the motion stage's rollouts start, read from the data set by training.

    It runs on the simulation's device before any worker starts, so that on a GPU the
    solver's modules are compiled here once and every worker loads them from warp's cache.
    """
    import dataclasses

    import numpy as np
    import torch

    from loosefit.atomic import atomic_path
    from loosefit.sim.driver import settle

    path = out / "rest_drape.npy"
    if path.is_file():
        return
    cloth = config.cloth
    if cloth.device != "cpu" and not torch.cuda.is_available():  # a cluster's head node
        cloth = dataclasses.replace(cloth, device="cpu")
    with one_torch_thread():
        drape = settle(avatar, template, cloth, config.fps)
    with atomic_path(path) as tmp:
        np.save(tmp, drape.astype(np.float32))


def _take_what_is_done(
    config: DatasetConfig,
    jobs: list[Job],
    manifest: dict,
    out: Path,
    avatar,
    template,
    *,
    reuse,
    progress: bool,
) -> None:
    """Clips taken from the ``reuse`` data set, and the clips of this one recorded under
    another pose correction or release of trapped cloth kept or removed (the manifest's
    migrations, :mod:`loosefit.sim.manifest`)."""
    if reuse is not None:
        taken = adopt_clips(config, jobs, manifest, out, Path(reuse))
        if progress and taken:
            tqdm.write(f"reused {len(taken)} clips from {reuse}: {', '.join(taken)}")
    kept, again = recheck_unfold(config, jobs, manifest, out, avatar)
    if kept or again:
        write_json_atomic(out / "manifest.json", manifest)
        if progress:
            tqdm.write(
                f"the pose correction changed: kept {', '.join(kept) or 'none'} (their "
                f"motion is the same); simulating again {', '.join(again) or 'none'}"
            )
    kept, again = recheck_release(config, jobs, manifest, out, avatar, template)
    if kept or again:
        write_json_atomic(out / "manifest.json", manifest)
        if progress:
            tqdm.write(
                f"release_depth changed to {config.cloth.release_depth}: kept "
                f"{', '.join(kept) or 'none'} (it never acts on them); simulating "
                f"again {', '.join(again) or 'none'}"
            )


def _units(
    config: DatasetConfig, todo: list[Job], avatar, batch: int
) -> tuple[list[list[Job]], dict[str, int]]:
    """The units of work (clips alone, or batches of up to ``batch`` clips of similar length,
    longest first, none shorter than half its batch's longest) and the frames each
    simulates (settle and blend included: the bar's estimate), by unit name."""
    settle = 0.0 if config.cloth.settle_once else config.cloth.settle_seconds
    preroll = round((settle + config.cloth.blend_seconds) * config.fps)
    length = {
        j.name: job_motion(config, j, avatar, unfold=False).num_frames + preroll for j in todo
    }
    if batch > 1:  # a clip waits for its batch's longest: none shorter than half of it
        groups: list[list[Job]] = []
        for job in sorted(todo, key=lambda j: (-length[j.name], j.name)):
            group = groups[-1] if groups else None
            if group and len(group) < batch and 2 * length[job.name] >= length[group[0].name]:
                group.append(job)
            else:
                groups.append([job])
    else:
        groups = [[j] for j in todo]
    frames_of = {unit_name(g): max(length[j.name] for j in g) for g in groups}
    return groups, frames_of


class _Progress:
    """The progress bar over every unit's frames, fed ``update(name, frame, total)``.

    A resumed unit first reports the frame after its last save: the frames before are not
    this run's work. A unit run again from its last save (a Ray task whose worker died)
    counts the frames done twice as work done twice. Where a unit's total differs from
    the estimate, the bar's total is corrected.
    """

    def __init__(self, frames_of: dict[str, int], bar) -> None:
        self.frames_of = frames_of  # the frames each unit simulates, by name
        self.bar = bar
        self.seen: dict[str, int] = {}  # the last frame each unit of work reported
        self.resumed: dict[str, int] = {}  # the frames each found on disk

    def update(self, name: str, k: int, total: int) -> None:
        seen, resumed, frames_of = self.seen, self.resumed, self.frames_of
        if name not in seen:  # a resumed unit first reports the frame after its last saved
            resumed[name] = seen[name] = k - 1
        elif k <= seen[name]:  # run again from its last save (a Ray task whose worker died):
            resumed[name] -= seen[name] - (k - 1)  # the frames done twice are work done twice
            seen[name] = k - 1
        if frames_of.get(name) != total - resumed[name]:  # the estimate was off: correct it
            frames_of[name] = total - resumed[name]
            self.bar.total = sum(frames_of.values())
            self.bar.refresh()
        self.bar.update(k - seen[name])
        seen[name] = k

    def close(self) -> None:
        self.bar.close()


class _Direct:
    """A stand-in for a progress queue that calls back at once (single process)."""

    def __init__(self, callback) -> None:
        self.put = lambda item: callback(*item)


def _run_in_pool(
    config: DatasetConfig,
    units: list[list[Job]],
    out_dir: str,
    resume_every: int,
    workers: int,
    on_progress: Callable[[str, int, int], None],
    *,
    record: Callable[[list[Job], list[dict]], None],
    prepared: dict[str, list] | None = None,
) -> None:
    """Simulate ``units`` in ``workers`` processes (:func:`~loosefit.sim.workers.serve`:
    each builds its worker once), in order, recording each as it finishes; ``prepared``:
    each unit's motions by unit name, or None (each worker makes its own).

    Raises:
        whatever a worker raised (its error, or the pool broken by a process that died).
    """
    tasks = [
        (group, out_dir, resume_every, None if prepared is None else prepared[unit_name(group)])
        for group in units
    ]
    run_in_processes(
        serve,
        (config,),
        tasks,
        workers,
        on_result=lambda index, entries: record(units[index], entries),
        on_wait=lambda progress: _drain(progress, on_progress),
    )


def _prepare(
    config: DatasetConfig, units: list[list[Job]], processes: int, progress: bool
) -> dict[str, list]:
    """Every unit's motions (:func:`~loosefit.sim.workers.prepare_motions`; ``units``
    longest first, so their clips are), by unit name, with a progress bar over the clips."""
    jobs = [j for g in units for j in g]
    bar = tqdm(
        total=len(jobs),
        unit="clip",
        desc=f"prepare the motions ({min(processes, len(jobs))} processes)",
        disable=not progress,
    )
    motions = prepare_motions(config, jobs, processes, on_done=lambda job, motion: bar.update())
    bar.close()
    of = {j.name: m for j, m in zip(jobs, motions, strict=True)}
    return {unit_name(g): [of[j.name] for j in g] for g in units}


def _drain(progress, on_progress: Callable[[str, int, int], None]) -> None:
    """Pass on every progress report waiting in the queue ``progress``."""
    while True:
        try:
            on_progress(*progress.get_nowait())
        except queue.Empty:
            return


def _finish(jobs: list[Job], manifest: dict, out: Path) -> dict:
    """The manifest of the whole data set: the split of the clips kept, the excluded ones,
    the summary; written, complete."""
    ok = [j for j in jobs if manifest["sequences"].get(j.name, {}).get("status") == "done"]
    manifest["split"] = {
        "train": [j.name for j in ok if not j.test],
        "test": [j.name for j in ok if j.test],
    }
    manifest["excluded"] = [
        n for n, e in manifest["sequences"].items() if e.get("status") != "done"
    ]
    manifest["summary"] = summarize(manifest)
    manifest["complete"] = True
    write_json_atomic(out / "manifest.json", manifest)
    return manifest
