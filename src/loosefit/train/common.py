"""What the training stages share: run folders, the optimiser step, resuming.

Checkpoint files are :mod:`loosefit.inference.checkpoints`'s.
"""

from __future__ import annotations

import contextlib
import os
import platform

import torch

from loosefit.errors import LoosefitInputError


def optimizer_step(
    optim: torch.optim.Optimizer,
    parameters,
    terms: dict,
    grad_clip: float,
    sums: dict[str, float],
    world: int = 1,
) -> None:
    """Backpropagate ``terms["total"]``, clip the gradient norm to ``grad_clip``, step, and
    add every term's value into ``sums`` (the epoch's running totals).

    Under torchrun (``world`` > 1, the network wrapped in DDP) ``terms`` are this
    process's share of the batch's terms (they sum to them over the processes): the
    loss is scaled by ``world`` against DDP's averaging of the gradients, and what is
    added into ``sums`` is the sum over the processes (the same on every one).
    """
    optim.zero_grad(set_to_none=True)
    (terms["total"] * world).backward()
    torch.nn.utils.clip_grad_norm_(parameters, grad_clip)
    optim.step()
    values = {k: v.detach() for k, v in terms.items()}
    for k, v in (all_mean(values) if world > 1 else values).items():
        sums[k] = sums.get(k, 0.0) + float(v)


def epoch_means(sums: dict[str, float], steps: int) -> dict[str, float]:
    """The epoch's mean terms per step (the training scaffold refuses a total that is not
    finite)."""
    return {k: v / max(steps, 1) for k, v in sums.items()}


def machine(device: str) -> str:
    """The machine a run ran on, for reports."""
    return (
        f"{platform.machine()}, {os.cpu_count()} CPUs, torch {torch.__version__}, "
        f"{torch.get_num_threads()} threads, {device}"
    )


# -- precision -------------------------------------------------------------------------------

PRECISIONS = ("fp32", "bf16")


def check_precision(source: str, precision: str) -> None:
    """A training configuration's ``precision``: "fp32" or "bf16".

    Raises:
        LoosefitInputError: anything else.
    """
    if precision not in PRECISIONS:
        raise LoosefitInputError(source, "precision", " or ".join(PRECISIONS), repr(precision))


def check_device_precision(precision: str, device: torch.device) -> None:
    """Refuse bf16 on a GPU without it (compute capability below 8.0).

    Raises:
        LoosefitInputError: ``precision`` "bf16" on such a GPU.
    """
    if (
        precision == "bf16"
        and device.type == "cuda"
        and not torch.cuda.is_bf16_supported(including_emulation=False)
    ):
        raise LoosefitInputError(
            "--precision",
            "precision",
            "fp32 on this GPU (bf16 needs compute capability 8.0 or above)",
            "bf16",
        )


def autocast(precision: str, device: torch.device):
    """The context the networks' forward passes run in: nothing for "fp32"; for "bf16",
    ``torch.autocast`` to bfloat16 (convolutions, linear layers and matrix products in
    bf16, the weights themselves float32). Callers cast what comes out to float32 and
    take their losses outside it."""
    if precision == "fp32":
        return contextlib.nullcontext()
    return torch.autocast(device_type=device.type, dtype=torch.bfloat16)


# -- several processes (torchrun) -------------------------------------------------------------


def distributed() -> tuple[int, int]:
    """(rank, world size) of a ``torch.distributed`` run (``torchrun``), (0, 1) otherwise."""
    import torch.distributed as dist

    if dist.is_available() and dist.is_initialized():
        return dist.get_rank(), dist.get_world_size()
    return 0, 1


def barrier() -> None:
    """Wait for every process of a distributed run (nothing alone)."""
    import torch.distributed as dist

    if distributed()[1] > 1:
        dist.barrier()


def shard(batch: int, rank: int, world: int) -> tuple[torch.Tensor, float]:
    """This process's items of a batch of ``batch`` (every ``world``-th from ``rank``) and
    their share of it. A process left without an item takes item 0 with share 0, so that
    every process still runs the step (DDP needs them all)."""
    mine = torch.arange(rank, batch, world)
    if len(mine) == 0:
        return torch.zeros(1, dtype=torch.long), 0.0
    return mine, len(mine) / batch


def all_mean(values: dict[str, torch.Tensor]) -> dict[str, float]:
    """Sum of ``values`` (each a process's weighted share) over the processes, as floats."""
    import torch.distributed as dist

    if distributed()[1] == 1:
        return {k: float(v) for k, v in values.items()}
    keys = sorted(values)
    t = torch.stack([values[k].float().reshape(()) for k in keys])
    dist.all_reduce(t)
    return dict(zip(keys, t.tolist(), strict=True))
