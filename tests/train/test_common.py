import os

import pytest
import torch

from loosefit.errors import LoosefitInputError
from loosefit.train.common import (
    all_mean,
    autocast,
    check_device_precision,
    check_precision,
    distributed,
    epoch_means,
    machine,
    optimizer_step,
    shard,
)


def test_an_optimizer_step_is_the_plain_sgd_step_with_a_clipped_gradient():
    w = torch.nn.Parameter(torch.tensor([1.0, 2.0]))
    x = torch.tensor([3.0, 4.0])  # the loss w . x has gradient x, of norm 5
    optim = torch.optim.SGD([w], lr=0.1)
    sums = {"total": 1.0}
    terms = {"total": w @ x, "fit": (w @ x) / 2}
    optimizer_step(optim, [w], terms, grad_clip=0.5, sums=sums)
    # the gradient clipped to norm 0.5: x / 10; one step of 0.1 of it
    torch.testing.assert_close(w.detach(), torch.tensor([1.0, 2.0]) - 0.1 * x / 10)
    assert sums == pytest.approx({"total": 1.0 + 11.0, "fit": 5.5})
    # a gradient under the clip is left whole, and the old one does not linger
    optimizer_step(optim, [w], {"total": w.sum()}, grad_clip=10.0, sums=sums)
    torch.testing.assert_close(w.detach(), torch.tensor([0.97 - 0.1, 1.96 - 0.1]))


def test_epoch_means_divide_by_the_steps():
    assert epoch_means({"total": 6.0, "fit": 3.0}, 3) == {"total": 2.0, "fit": 1.0}
    assert epoch_means({"total": 6.0}, 0) == {"total": 6.0}


def test_precisions_are_checked():
    check_precision("cfg", "bf16")
    with pytest.raises(LoosefitInputError) as err:
        check_precision("TrainConfig", "fp16")
    assert (err.value.source, err.value.field) == ("TrainConfig", "precision")
    assert (err.value.expected, err.value.found) == ("fp32 or bf16", "'fp16'")
    check_device_precision("bf16", torch.device("cpu"))  # the CPU has bf16 (no refusal)


def test_autocast_runs_products_in_bfloat16_only_when_asked():
    a, b = torch.randn(4, 8), torch.randn(8, 2)
    cpu = torch.device("cpu")
    with autocast("fp32", cpu):
        assert (a @ b).dtype == torch.float32
    with autocast("bf16", cpu):
        out = a @ b
    assert out.dtype == torch.bfloat16
    torch.testing.assert_close(out.float(), a @ b, atol=0.1, rtol=0.05)


@pytest.mark.parametrize(("batch", "world"), [(10, 3), (8, 4), (5, 1), (7, 2)])
def test_shards_cover_the_batch_once(batch, world):
    parts = [shard(batch, rank, world) for rank in range(world)]
    for rank, (mine, share) in enumerate(parts):
        assert mine.tolist() == [i for i in range(batch) if i % world == rank]
        assert share == pytest.approx(len(mine) / batch)
    assert sorted(i for mine, _ in parts for i in mine.tolist()) == list(range(batch))
    assert sum(share for _, share in parts) == pytest.approx(1.0)


def test_a_process_without_items_still_steps_with_no_share():
    mine, share = shard(2, rank=2, world=3)
    assert mine.tolist() == [0] and share == 0.0


def test_alone_a_run_is_rank_zero_of_one_and_its_means_are_its_values():
    assert distributed() == (0, 1)
    out = all_mean({"total": torch.tensor(1.5), "fit": torch.tensor([0.25])})
    assert out == {"total": 1.5, "fit": 0.25}
    assert all(type(v) is float for v in out.values())


def test_the_machine_line_names_the_device_and_cpus():
    line = machine("cuda:1")
    assert line.endswith(", cuda:1") and f"{os.cpu_count()} CPUs" in line
    assert f"torch {torch.__version__}" in line
