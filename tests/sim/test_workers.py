"""The workers of a data set run (loosefit.sim.workers)."""

from __future__ import annotations

import numpy as np

import loosefit.sim.workers as workers
from loosefit.sim.dataset_config import make_garment
from loosefit.sim.presets import preset
from loosefit.sim.workers import one_torch_thread


def test_the_data_set_s_garment_is_the_workers_whatever_the_caller_s_threads():
    # The avatar's rest shape differs in a float's last bit between torch thread counts;
    # generate builds template.npz on one thread, as the workers build the garment they
    # simulate, and gives the caller its thread count back.
    import torch

    from loosefit.body.avatar import Avatar, AvatarConfig

    config = preset("tiny")
    threads = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        with one_torch_thread():
            assert torch.get_num_threads() == 1
            avatar = Avatar(AvatarConfig(shape=dict(config.shape)))
            ours = make_garment(config.garment, avatar).vertices
        assert torch.get_num_threads() == 2
        worker = workers.Worker.build(config)  # what a worker process does first
        np.testing.assert_array_equal(worker.template.vertices, ours)
    finally:
        torch.set_num_threads(threads)


def test_motions_prepared_ahead_are_the_workers_own_to_the_bit():
    """A batch's motions are prepared before the batch (``prepare_motions``; in other
    processes: tests/sim/test_generate.py's batch): loaded and pose-corrected as the worker
    that simulates them would, the same to the bit."""
    import pytest

    from loosefit.errors import LoosefitInputError
    from loosefit.sim.jobs import Job, plan_jobs

    config = preset("tiny")
    jobs = plan_jobs(config)[:2]
    worker = workers.Worker.build(config)
    seen = []
    ahead = workers.prepare_motions(config, jobs, 1, on_done=lambda j, m: seen.append(j.name))
    assert seen == [j.name for j in jobs]
    for job, got in zip(jobs, ahead, strict=True):
        want = worker.motion(job)
        assert got.name == want.name and got.fps == want.fps
        np.testing.assert_array_equal(got.rotations, want.rotations)
        np.testing.assert_array_equal(got.root_translation, want.root_translation)
        assert got.meta == want.meta  # the pose correction's own figures
    with pytest.raises(LoosefitInputError, match="processes"):
        workers.prepare_motions(config, jobs, 0)
    # a clip that cannot be prepared stops the run with its own error
    missing = Job("gone", "/nonexistent/gone.bvh", 0, False)
    with pytest.raises(LoosefitInputError, match="gone.bvh"):
        workers.prepare_motions(config, [jobs[0], missing], 1)


def test_a_pool_worker_simulates_the_motions_it_is_given(monkeypatch):
    """``serve`` hands each unit's prepared motions (or None: its own) to ``Worker.run``."""
    import queue

    given = []

    class Stub:
        def run(self, jobs, out_dir, resume_every, motions=None):
            given.append((jobs, out_dir, resume_every, motions))
            return [{"name": j} for j in jobs]

    build = classmethod(lambda cls, cfg, progress=None: Stub())
    monkeypatch.setattr(workers.Worker, "build", build)
    monkeypatch.setattr(workers, "exit_with_parent", lambda: None)
    units, results = queue.Queue(), queue.Queue()
    units.put((0, ["a", "b"], "out", 50, ["motion a", "motion b"]))
    units.put((1, ["c"], "out", 7, None))
    units.put(None)
    workers.serve(preset("tiny"), units, results, None)
    assert given == [(["a", "b"], "out", 50, ["motion a", "motion b"]), (["c"], "out", 7, None)]
    assert [results.get_nowait() for _ in range(2)] == [
        (0, [{"name": "a"}, {"name": "b"}]),
        (1, [{"name": "c"}]),
    ]
