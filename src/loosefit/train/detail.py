"""Training the detail enhancement module (paper 3.4, Eqs. 13-15) on a frozen motion stage.

**What it learns from.** At inference the detail generator sees the motion stage's
rollouts, never the generative model's reconstructions of the simulation, so it is
trained on exactly those: every training clip (and its mirror, when the motion stage
was trained on mirrored clips) is rolled out once by the frozen motion stage from its
first frame, as ``loosefit animate`` would, and each frame gives a pair (the decoded
garment ``V_t`` and its code ``Z_t``; the simulated ``V*_t``), all in the root frame.
The pairs are computed once per run and kept in the run folder (``pairs.pt``). A
module trained on reconstructions would learn to sharpen garments that are already
close to the truth and meet rollouts 2-3 times as far off at inference.

**The loop.** Batches of pairs; the generator's input is data (the paper's truncated
gradient: nothing flows back into the frozen stages); per step the discriminator
takes one step on Eq. 14 (real: ``S*``, fake: ``S_f`` detached), then the generator
on Eq. 13 plus ``adversarial`` times its side of Eq. 14. ``adversarial=False`` drops
the discriminator (Table 2's middle row). A run is a folder (``config.json``,
``checkpoint.pt`` written atomically every epoch and resumed, ``model.pt``: the
generator alone in half precision, ``report.json/.md``).
"""

from __future__ import annotations

import os
import resource
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch

from loosefit.body.mirror import mirror_garment, mirror_motion, vertex_twins
from loosefit.data.format import DatasetReader, write_json_atomic
from loosefit.errors import LoosefitInputError
from loosefit.garment.fingerprint import same_garment
from loosefit.garment.mesh_checks import unique_edges
from loosefit.geometry.laplacian import Laplacian
from loosefit.inference.animator import (
    AnimationModel,
    load_animation_model,
    load_detail_model,
    stage_fingerprints,
)
from loosefit.inference.checkpoints import (
    DETAIL_FORMAT,
    load_weights,
    read_checkpoint_file,
    save_atomic,
)
from loosefit.model.detail import (
    DetailConfig,
    DetailGenerator,
    MultiScaleDiscriminator,
    detail_geometry_loss,
    edge_length_loss,
    lsgan_discriminator_loss,
    lsgan_generator_loss,
)
from loosefit.model.motion_features import to_root_frame
from loosefit.model.rollout import MOTION_ONLY, Stages, motion_root_frames
from loosefit.train.common import apply_overrides, machine, open_run, restore_training
from loosefit.train.motion import training_config

CHECKPOINT_FORMAT = DETAIL_FORMAT


@dataclass
class DetailLossConfig:
    """Eqs. 13-15 and the length unit of the geometry terms."""

    laplacian: float = 1.0  # Eq. 13's Laplacian term (1 in the paper)
    adversarial: float = 0.1  # the generator's side of Eq. 14 against Eq. 13 (in cm)
    length_scale: float = 100.0  # metres to centimetres, as in the other stages' losses
    edge: float = 0.0  # L1 of edge lengths (not in Eq. 13; 0: the paper's loss)


@dataclass
class TrainDetailConfig:
    """One training run of the detail module."""

    model: DetailConfig = field(default_factory=DetailConfig)
    loss: DetailLossConfig = field(default_factory=DetailLossConfig)
    discriminator: bool = True  # False: the ablation without D_ms (Table 2's middle row)
    epochs: int = 100
    batch_size: int = 8
    lr: float = 2.0e-4
    weight_decay: float = 1.0e-3  # the paper's Adam weight decay, for every network
    mirror: bool | None = None  # also the mirrored training clips; None: as the motion stage
    max_frames: int | None = None  # per clip, for quick runs
    checkpoint_every: int = 1  # epochs
    seed: int = 0
    device: str = "cpu"
    # warm start: a detail checkpoint (a run's, or a packaged detail.pt) of the same
    # configuration whose generator (and discriminator, where it has one) the run starts
    # from, whatever motion stage it was trained on (fine-tuning to a new one)
    init: str | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.discriminator, bool):
            raise LoosefitInputError(
                "TrainDetailConfig", "discriminator", "true or false", repr(self.discriminator)
            )
        for name in ("epochs", "batch_size", "checkpoint_every"):
            v = getattr(self, name)
            if not (isinstance(v, int) and v >= 1):
                raise LoosefitInputError("TrainDetailConfig", name, "an integer >= 1", v)

    @classmethod
    def preset(cls, name: str, **overrides) -> TrainDetailConfig:
        """``full``: the paper's (100 epochs, batch 8, lr 2e-4); ``cpu``: 12 epochs of batch 16
        at lr 5e-4 with a discriminator of half the width (16, 32, 64 channels: its
        convolutions are most of a step's time on a CPU), under an hour on salsa's
        rollouts on one core."""
        if name == "full":
            cfg = cls()
        elif name == "cpu":
            cfg = cls(
                epochs=12, batch_size=16, lr=5.0e-4, model=DetailConfig(disc_channels=(16, 32, 64))
            )
        else:
            raise LoosefitInputError("--preset", "preset", "full or cpu", repr(name))
        apply_overrides(cfg, overrides).__post_init__()
        return cfg

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> TrainDetailConfig:
        d = dict(d)
        d["model"] = DetailConfig(**d["model"])
        d["loss"] = DetailLossConfig(**d["loss"])
        return cls(**d)


# -- the data: the frozen motion stage's rollouts ----------------------------------------


@dataclass
class DetailPairs:
    """Training pairs, all in the root frame of their frame.

    Attributes:
        decoded: (N, V, 3) the motion stage's garments V_t.
        codes: (N, latent) their codes Z_t.
        target: (N, V, 3) the simulated garments V*_t.
        clips: the clips they come from, in order.
    """

    decoded: torch.Tensor
    codes: torch.Tensor
    target: torch.Tensor
    clips: list[str]


@torch.no_grad()
def rollout_pairs(
    model: AnimationModel,
    reader: DatasetReader,
    split: str = "train",
    mirror: bool = False,
    max_frames: int | None = None,
    log=print,
) -> DetailPairs:
    """Roll every clip of a split out with the motion stage alone and pair each frame with
    the simulation (mirrored clips too with ``mirror``)."""
    names = reader.training_clips(split)
    twins = vertex_twins(reader.template.vertices) if mirror else None
    decoded, codes, target, clips = [], [], [], []
    for name in names:
        seq = reader.read(name)
        motion = seq.motion if max_frames is None else seq.motion.slice(0, max_frames)
        truth = seq.garment_vertices[: motion.num_frames]
        versions = [(name, motion, truth)]
        if mirror:
            versions.append((f"{name}~mirror", mirror_motion(motion), mirror_garment(truth, twins)))
        for label, m, v in versions:
            t0 = time.perf_counter()
            result = model.animate(m, stages=MOTION_ONLY)
            H, p, _ = motion_root_frames(m, model.floor_height, model.rollout_config)
            decoded.append(to_root_frame(torch.from_numpy(result.vertices), H, p))
            target.append(to_root_frame(torch.as_tensor(np.asarray(v, np.float32)), H, p))
            codes.append(torch.from_numpy(result.codes))
            clips.append(label)
            log(f"rolled out {label}: {m.num_frames} frames in {time.perf_counter() - t0:.1f} s")
    return DetailPairs(torch.cat(decoded), torch.cat(codes), torch.cat(target), clips)


# -- training --------------------------------------------------------------------------------


def train_detail(
    data: str | Path,
    motion: str | Path,
    out: str | Path,
    config: TrainDetailConfig,
    generative: str | Path | None = None,
    log=print,
    progress: bool = True,
) -> dict:
    """Train (or resume) the detail module on a frozen motion stage's rollouts.

    Args:
        data: the dataset the motion stage was trained on.
        motion: the motion stage's checkpoint (``model.pt``; frozen here).
        out: the run folder; an existing run with the same configuration resumes.
        config: the run.
        generative: the generative checkpoint, if not the one the motion stage records.
        log: where progress lines go.
        progress: show a tqdm bar.

    Returns:
        The report (also ``out/report.json`` and ``out/report.md``).
    """
    from torch.utils.tensorboard import SummaryWriter
    from tqdm import tqdm

    out = Path(out)
    reader = DatasetReader(data)
    mpath = Path(motion).resolve()
    model = load_animation_model(mpath, generative, config.device)
    fingerprints = stage_fingerprints(model)
    if not same_garment(model.template, reader.template):
        raise LoosefitInputError(
            reader.root, "template", f"the garment {mpath.name} was trained on", "another garment"
        )
    mirror = config.mirror
    if mirror is None:  # as the motion stage was trained (a packaged one: not mirrored)
        trained = training_config(mpath)
        mirror = bool(trained is not None and trained.mirror)
    open_run(
        out,
        {
            "dataset": str(Path(data).resolve()),
            "motion": fingerprints["motion"],
            "train": config.to_dict(),
        },
    )
    torch.manual_seed(config.seed)
    gen = torch.Generator().manual_seed(config.seed)

    # 1. the pairs: the frozen motion stage's rollouts of the training clips (cached)
    pairs_path = out / "pairs.pt"
    if pairs_path.is_file():
        saved = torch.load(pairs_path, weights_only=True)
        pairs = DetailPairs(saved["decoded"], saved["codes"], saved["target"], saved["clips"])
    else:
        pairs = rollout_pairs(model, reader, "train", mirror, config.max_frames, log)
        save_atomic(asdict(pairs), pairs_path)
    N = len(pairs.codes)
    log(f"{N} training pairs from {len(pairs.clips)} rollouts")

    # 2. the networks
    t = model.template
    dev = config.device
    G = DetailGenerator(t.faces, t.num_vertices, model.encoder.latent, config.model).to(dev)
    D = MultiScaleDiscriminator(model.generative.config.uv_size, config.model).to(dev)
    uv = model.generative.uv
    lap = Laplacian(t.faces, t.num_vertices).to(dev)
    edges = torch.from_numpy(unique_edges(t.faces)[0]).t().to(dev)  # (2, E) each edge once
    opt_g = torch.optim.Adam(G.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    opt_d = torch.optim.Adam(D.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    ckpt_path = out / "checkpoint.pt"
    meta = {
        "model_config": asdict(config.model),
        "config": config.to_dict(),
        "fingerprints": fingerprints,
        "motion_checkpoint": {
            "relative": os.path.relpath(mpath, out.resolve()),
            "absolute": str(mpath),
        },
        "dataset": str(Path(data).resolve()),
    }
    epoch, history = 0, []
    if ckpt_path.is_file():
        epoch, history = restore_training(
            read_checkpoint_file(ckpt_path, DETAIL_FORMAT, dev),
            {"model": G, "discriminator": D, "optimizer": opt_g, "optimizer_discriminator": opt_d},
            gen,
        )
        log(f"resumed {ckpt_path} at epoch {epoch}")
    elif config.init:
        saved = read_checkpoint_file(config.init, DETAIL_FORMAT, dev)
        load_weights(G, saved["model"], Path(config.init), "this detail configuration")
        if "discriminator" in saved:
            load_weights(
                D, saved["discriminator"], Path(config.init), "this discriminator configuration"
            )
        log(f"started from the weights of {config.init}")

    # 3. the loop
    writer = SummaryWriter(str(out))
    bar = tqdm(
        total=config.epochs, initial=epoch, desc="train detail", unit="epoch", disable=not progress
    )
    t_start, epochs_run = time.perf_counter(), 0
    cl = config.loss
    while epoch < config.epochs:
        G.train()
        D.train()
        order = torch.randperm(N, generator=gen)
        sums: dict[str, float] = {}
        steps = 0
        for b in range(0, N, config.batch_size):
            idx = order[b : b + config.batch_size]
            v = pairs.decoded[idx].to(dev)  # (B, V, 3): data, no gradient into the motion stage
            z, target = pairs.codes[idx].to(dev), pairs.target[idx].to(dev)
            final = v + G(v, z)
            position, laplacian = detail_geometry_loss(
                final, target, lap, cl.length_scale, cl.laplacian
            )
            terms = {"position": position, "laplacian": laplacian}
            loss = position + laplacian
            if cl.edge > 0:
                terms["edge"] = cl.edge * edge_length_loss(final, target, edges, cl.length_scale)
                loss = loss + terms["edge"]
            if config.discriminator:
                fake, real = uv.encode(final), uv.encode(target)  # (B, 3, H, W)
                d_loss = lsgan_discriminator_loss(D(real), D(fake.detach()))
                opt_d.zero_grad(set_to_none=True)
                d_loss.backward()
                opt_d.step()
                g_adv = lsgan_generator_loss(D(fake))
                loss = loss + cl.adversarial * g_adv
                terms.update(discriminator=d_loss, adversarial=g_adv)
            opt_g.zero_grad(set_to_none=True)
            loss.backward()
            opt_g.step()
            terms["total"] = loss
            steps += 1
            for k, val in terms.items():
                sums[k] = sums.get(k, 0.0) + float(val.detach())
            bar.set_postfix(
                step=f"{steps}/{-(-N // config.batch_size)}", l1=f"{sums['position'] / steps:.3f}"
            )
        sums = {k: val / max(steps, 1) for k, val in sums.items()}
        if not np.isfinite(sums["total"]):
            raise RuntimeError(f"training diverged at epoch {epoch + 1}: loss {sums['total']}")
        epoch += 1
        epochs_run += 1
        history.append({"epoch": epoch, **sums})
        for k, val in sums.items():
            writer.add_scalar(f"loss/{k}", val, epoch)
        bar.update(1)
        if epoch % config.checkpoint_every == 0 or epoch == config.epochs:
            save_atomic(
                {
                    "format": CHECKPOINT_FORMAT,
                    **meta,
                    "model": G.state_dict(),
                    "discriminator": D.state_dict(),
                    "optimizer": opt_g.state_dict(),
                    "optimizer_discriminator": opt_d.state_dict(),
                    "epoch": epoch,
                    "history": history,
                    "rng": torch.get_rng_state(),
                    "sampling_rng": gen.get_state(),
                },
                ckpt_path,
            )
    bar.close()
    seconds = time.perf_counter() - t_start
    weights = {k: v.half() for k, v in G.state_dict().items()}
    save_atomic(
        {"format": CHECKPOINT_FORMAT, **meta, "model": weights, "epoch": epoch}, out / "model.pt"
    )

    # 4. the report: the held-out clips before and after the module (no collision handling)
    from loosefit.train.motion import evaluate_rollouts

    trained = load_detail_model(out / "model.pt", mpath, generative, dev)
    report = {
        "discriminator": config.discriminator,
        "dataset": str(Path(data).resolve()),
        "motion": str(mpath),
        "epochs": config.epochs,
        "pairs": N,
        "parameters": sum(p.numel() for p in G.parameters()),
        "seconds_per_epoch": seconds / epochs_run if epochs_run else None,
        "peak_memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "machine": machine(dev),
        "final_loss": history[-1] if history else None,
        "history": history,
        "test_without": evaluate_rollouts(
            trained, reader, "test", surface=False, stages=MOTION_ONLY
        ),
        "test_with": evaluate_rollouts(
            trained,
            reader,
            "test",
            surface=False,
            stages=Stages(detail=True, lengths=False, collision=False),
        ),
    }
    write_json_atomic(out / "report.json", report)
    (out / "report.md").write_text(format_report(report))
    writer.close()
    return report


def format_report(report: dict) -> str:
    """A Markdown summary of a detail run's report."""
    a, b = report["test_without"], report["test_with"]
    spe = report.get("seconds_per_epoch")
    return "\n".join(
        [
            f"# Detail module ({'with' if report['discriminator'] else 'w/o'} D_ms), "
            f"{report['epochs']} epochs on {report['pairs']} rollout frames",
            "",
            "| held-out rollouts | RMSE (cm) |",
            "|---|---:|",
            f"| motion stage alone | {a['rmse_cm']:.3f} |",
            f"| with the detail module | {b['rmse_cm']:.3f} |",
            "",
            f"{report['parameters']:,} generator parameters; "
            + (f"{spe:.1f} s per epoch; " if spe else "")
            + f"peak memory {report['peak_memory_mb']:.0f} MB; {report['machine']}.",
            "",
        ]
    )
