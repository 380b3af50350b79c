"""One window of the motion encoder's training: the loss's weights (Eqs. 10-12,
:class:`MotionLossConfig`) and the frames ``start:stop`` of a batch of clips run along the
rollout timeline (:func:`run_window`), each frame's previous state the truth or the
encoder's own prediction; where a process's clips sit in a batch shared among processes
(:class:`BatchPart`). The stage that runs the windows clip by clip:
:mod:`loosefit.train.motion`.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from loosefit.errors import LoosefitInputError
from loosefit.inference.rollout import change_frame
from loosefit.model.generative import GarmentGenerativeModel
from loosefit.model.losses import (
    ClothStructure,
    PhysicsLossConfig,
    hem_radius,
    physics_terms,
    speed_error,
)
from loosefit.model.motion_encoder import DynamicMotionEncoder
from loosefit.train.clips import Clip, stack_clips
from loosefit.train.common import autocast, shard


@dataclass
class MotionLossConfig:
    """Eqs. 10-12 and the length unit of the geometry terms, and the optional terms beyond
    the paper (0: off): the physics terms of :mod:`loosefit.model.losses` (the collision
    term keeps each vertex on the outer side of the body where the simulation's lies: the
    tangent plane at its closest body point, found once per training frame, so that a
    prediction whose raised knee comes through the front of the skirt pays), the hem's flare,
    its mean distance from the root's vertical axis against the simulation's (a network that
    averages fold configurations pulls the hem in), and the vertices' speed against the
    simulation's (an average of chaotic runs moves less than any one of them; the term asks
    for the runs' energy, whatever the direction)."""

    laplacian: float = 1.5  # lambda_4: weight of the Laplacian coordinates' squared error
    latent: float = 0.5  # lambda_5: weight of the code's squared error
    length_scale: float = 100.0  # lengths times this in the loss: metres to centimetres
    membrane: float = 0.0  # weight of edge lengths against rest; 0: off
    bending: float = 0.0  # weight of dihedral angles against rest; 0: off
    collision: float = 0.0  # weight of the depth behind the simulation's body contacts; 0: off
    collision_epsilon: float = 0.002  # m; the collision term's margin
    flare: float = 0.0  # weight of the hem flare's squared error, in the length unit; 0: off
    speed: float = 0.0  # weight of the vertex speeds' squared error (length unit a frame); 0: off

    def __post_init__(self) -> None:
        for name in ("flare", "speed"):
            w = getattr(self, name)
            if not (isinstance(w, (int, float)) and w >= 0):
                raise LoosefitInputError("MotionLossConfig", name, "a weight >= 0", w)
        PhysicsLossConfig(self.membrane, self.bending, self.collision, self.collision_epsilon)


@dataclass
class BatchPart:
    """Where one process's clips sit in a batch shared among processes (torchrun).

    Attributes:
        rows: (b,) long, CPU: this process's clips among the batch's B.
        preroll: (B,) and ``length`` (B,), CPU: every clip's of the whole batch.
        weight: 1, or 0 for a process left without a clip (it runs clip 0 for nothing,
            as :func:`~loosefit.train.common.shard` gives it).
    """

    rows: torch.Tensor
    preroll: torch.Tensor
    length: torch.Tensor
    weight: float = 1.0

    @classmethod
    def whole(cls, batch: dict[str, torch.Tensor]) -> BatchPart:
        """A batch run by one process alone."""
        B = len(batch["length"])
        return cls(torch.arange(B), batch["preroll"].cpu(), batch["length"].cpu())

    def count(self, start: int, stop: int) -> int:
        """The valid (clip, frame) pairs of the whole batch among timeline frames
        ``start:stop``: the frames ``P <= t < length`` of each clip."""
        first = self.preroll.clamp(min=start)
        last = self.length.clamp(max=stop)
        return int((last - first).clamp(min=0).sum())


@dataclass
class WindowResult:
    """What one window of training gives back (:func:`run_window`).

    Attributes:
        terms: the loss terms, 0-d each: this process's share of the means over the whole
            batch's valid (clip, frame) pairs of the window (they sum to them over the
            processes); ``total`` differentiable w.r.t. the encoder through this window
            only, and without a gradient when the window holds no valid pair.
        hidden: (b, gru) the GRU state after the window's last frame, detached.
        previous: (b, V, 3) the garment of the window's last frame in its root frame, as
            the next window's first frame reads it (the truth or the prediction), detached.
    """

    terms: dict[str, torch.Tensor]
    hidden: torch.Tensor
    previous: torch.Tensor


def share_batch(
    clips: list[Clip], rank: int, world: int, device: torch.device
) -> tuple[dict[str, torch.Tensor], BatchPart]:
    """This process's clips of a batch, stacked (padded to the whole batch's frames) on
    ``device``, and where they sit in the batch."""
    mine, share = shard(len(clips), rank, world)
    batch = stack_clips([clips[i] for i in mine.tolist()], clips)
    preroll, length = (torch.tensor([getattr(c, a) for c in clips]) for a in ("preroll", "length"))
    part = BatchPart(mine, preroll, length, 1.0 if share > 0 else 0.0)
    return {k: v.to(device) for k, v in batch.items()}, part


def window_physics(
    v: torch.Tensor,
    structure: ClothStructure | None,
    loss: MotionLossConfig,
    batch: dict[str, torch.Tensor],
    rows: torch.Tensor,
    k: torch.Tensor,
) -> dict[str, torch.Tensor]:
    """The physics terms of ``loss`` (those with a weight) of one frame's predictions
    ``v`` (b, V, 3), (b,) each; the collision term against the body contacts of each
    clip's motion frame ``k`` (b,) in ``batch``."""
    if not (loss.membrane > 0 or loss.bending > 0 or loss.collision > 0):
        return {}
    touch = None
    if loss.collision > 0:
        if "contact_points" not in batch:
            raise ValueError("the collision term needs the clips' body contacts")
        touch = (batch["contact_points"][rows, k], batch["contact_normals"][rows, k])
    return physics_terms(v, structure, loss, touch, loss.length_scale)


def run_window(
    encoder: DynamicMotionEncoder,
    generative: GarmentGenerativeModel,
    laplacian,
    batch: dict[str, torch.Tensor],
    start: int,
    stop: int,
    *,
    hidden: torch.Tensor,
    previous: torch.Tensor,
    teacher: float,
    loss: MotionLossConfig,
    generator: torch.Generator | None = None,
    noise: float = 0.0,
    unroll: bool = False,
    part: BatchPart | None = None,
    precision: str = "fp32",
    structure: ClothStructure | None = None,
    hem: torch.Tensor | None = None,
) -> WindowResult:
    """Frames ``start:stop`` of stacked clips: the loss and the state to carry on.

    Args:
        encoder, generative, laplacian: the networks (the generative one frozen; the
            encoder may be wrapped in DDP).
        batch: :func:`~loosefit.train.clips.stack_clips` of b clips, on the networks' device.
        start, stop: the window, on the rollout timeline.
        hidden: (b, gru) the GRU state after frame ``start - 1`` (detached here).
        previous: (b, V, 3) the garment of frame ``start - 1`` in its root frame.
        teacher: the chance that a frame's previous state is the ground truth.
        loss: the weights.
        generator: draws the teacher choices (and the noise), on the CPU.
        noise: std (m) of Gaussian noise added to a ground-truth previous state.
        unroll: keep the encoder's own prediction, fed back as the next frame's
            previous state, in the graph (within this window; it is detached at the
            window's start like the GRU state).
        part: where ``batch`` sits in a batch of B clips shared among processes
            (default: it is the whole batch). The draws are made for all B clips.
        precision: the forward passes' ("fp32" or "bf16"; the loss is float32).
        structure: the garment's edges and hinges, for the physics terms of ``loss``
            (needed when one has a weight).
        hem: (H,) the hem's vertices, for the flare term of ``loss`` (needed when it has
            a weight).

    Returns:
        :class:`WindowResult`: the loss terms, the GRU state and the previous garment to
        carry on.
    """
    s = loss.length_scale
    part = BatchPart.whole(batch) if part is None else part
    device = previous.device
    hidden = hidden.detach()
    previous = previous.detach()
    P, H, p = batch["preroll"], batch["heading"], batch["origin"]
    rows = torch.arange(len(P), device=device)
    weight = torch.full((len(P),), float(part.weight), device=device)  # (b,)
    sums = {"geometry": 0.0, "laplacian": 0.0, "latent": 0.0}
    if loss.speed > 0:
        sums["speed"] = 0.0  # reported even for a window with no frame that has it
    own = None  # the encoder's own prediction of the frame before (the speed term's)
    for t in range(start, stop):
        if t > 0:
            previous = change_frame(previous, H[:, t - 1], p[:, t - 1], H[:, t], p[:, t])
            if own is not None:
                own = change_frame(own, H[:, t - 1], p[:, t - 1], H[:, t], p[:, t])
        with autocast(precision, device):
            z, hidden = encoder(batch["features"][:, t], previous, hidden)
            v = generative.decode(z)["vertices"]
        z, hidden, v = z.float(), hidden.float(), v.float()  # (b, latent), (b, gru), (b, V, 3)
        every = (t >= part.preroll) & (t < part.length)  # (B,) the whole batch's motion frames
        k = (t - P).clamp(0, batch["target"].shape[1] - 1)  # (b,) motion frame
        vt, zt = batch["target"][rows, k], batch["latent"][rows, k]  # (b, V, 3), (b, latent)
        if every.any():
            # sums over this process's valid clips (the others weigh 0, so that every
            # process's loss reaches every weight, as DDP needs)
            w = every[part.rows].to(device) * weight  # (b,)
            geometry = (s * v - s * vt).pow(2).sum(-1).mean(-1)  # (b,)
            lap = (s * laplacian(v) - s * laplacian(vt)).pow(2).sum(-1).mean(-1)
            sums["geometry"] = sums["geometry"] + (w * geometry).sum()
            sums["laplacian"] = sums["laplacian"] + loss.laplacian * (w * lap).sum()
            sums["latent"] = sums["latent"] + loss.latent * (w * (z - zt).pow(2).sum(-1)).sum()
            for key, e in window_physics(v, structure, loss, batch, rows, k).items():
                sums[key] = sums.get(key, 0.0) + (w * e).sum()  # (b,) each
            if loss.flare > 0:
                if hem is None:
                    raise ValueError("the flare term needs the garment's hem vertices")
                d = s * (hem_radius(v, hem) - hem_radius(vt, hem))  # (b,)
                sums["flare"] = sums.get("flare", 0.0) + loss.flare * (w * d.pow(2)).sum()
            if loss.speed > 0 and own is not None:
                # the encoder's step from its own prediction of the frame before (whatever
                # it was given: a step from the truth would measure its error), against the
                # truth's step, both in this frame's root frame. A clip's first motion frame
                # steps from the rest drape, and a window's first frame has no prediction
                # before it in the window: weight 0
                kb = (k - 1).clamp(min=0)
                before = change_frame(
                    batch["target"][rows, kb], H[:, t - 1], p[:, t - 1], H[:, t], p[:, t]
                )
                stepped = w * ((t - P) >= 1).to(device)  # (b,)
                e = speed_error(s * v, s * own, s * vt, s * before)  # (b,)
                sums["speed"] = sums["speed"] + loss.speed * (stepped * e).sum()
        previous = v if unroll else v.detach()
        own = previous if loss.speed > 0 else None
        if teacher > 0:
            draw = torch.rand(len(every), generator=generator)  # (B,) the whole batch's
            use = (draw < teacher) & every
            if use.any():
                gt = vt
                if noise > 0:
                    jitter = torch.randn((len(every), *vt.shape[1:]), generator=generator)
                    gt = gt + noise * jitter[part.rows].to(device)
                previous = torch.where(use[part.rows].to(device)[:, None, None], gt, previous)
    count = max(part.count(start, stop), 1)
    terms = {
        k: v / count if torch.is_tensor(v) else torch.tensor(v, device=device)
        for k, v in sums.items()
    }
    terms["total"] = sum(terms.values())
    return WindowResult(terms, hidden.detach(), previous.detach())
