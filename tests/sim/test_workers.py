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
