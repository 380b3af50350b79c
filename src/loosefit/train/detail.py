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
the discriminator (Table 2's middle row). A run is a folder of the training scaffold
(:mod:`loosefit.train.loop`: ``config.json``, ``checkpoint.pt`` written atomically
every epoch and resumed, ``report.json/.md``) plus ``pairs.pt`` and ``model.pt``: the
generator alone in half precision.
"""

from __future__ import annotations

import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import ClassVar

import numpy as np
import torch

from loosefit.data.format import DatasetReader
from loosefit.errors import LoosefitInputError
from loosefit.eval.rollouts import evaluate_rollouts
from loosefit.garment.fingerprint import same_garment
from loosefit.geometry.edges import unique_edges
from loosefit.geometry.laplacian import Laplacian
from loosefit.inference.animator import (
    AnimationModel,
    load_animation_model,
    load_detail_model,
)
from loosefit.inference.checkpoints import (
    DETAIL_FORMAT,
    load_weights,
    read_checkpoint_file,
    save_atomic,
    stage_fingerprints,
)
from loosefit.inference.rollout import motion_root_frames
from loosefit.inference.stages import MOTION_ONLY, Stages
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
from loosefit.train.clips import clip_versions
from loosefit.train.common import epoch_means
from loosefit.train.loop import Run, Trainer, TrainerConfig, adam, cost_line, train
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
class TrainDetailConfig(TrainerConfig):
    """One training run of the detail module (the shared fields: :class:`TrainerConfig`)."""

    epochs: int = 100  # the paper's
    batch_size: int = 8  # pairs per step, the paper's
    lr: float = 2.0e-4  # the paper's, for both networks
    checkpoint_every: int = 1  # epochs
    model: DetailConfig = field(default_factory=DetailConfig)  # the generator, discriminator
    loss: DetailLossConfig = field(default_factory=DetailLossConfig)  # Eqs. 13-15's weights
    discriminator: bool = True  # False: the ablation without D_ms (Table 2's middle row)
    mirror: bool | None = None  # also the mirrored training clips; None: as the motion stage
    init: str | None = None  # warm start: a detail checkpoint of this configuration

    # ``full``: the paper's (100 epochs, batch 8, lr 2e-4); ``cpu``: 12 epochs of batch 16 at
    # lr 5e-4 with a discriminator of half the width (16, 32, 64 channels; the figures:
    # docs/design/notes/train_detail.md)
    PRESETS: ClassVar[dict[str, dict]] = {
        "full": {},
        "cpu": {
            "epochs": 12,
            "batch_size": 16,
            "lr": 5.0e-4,
            "model": DetailConfig(disc_channels=(16, 32, 64)),
        },
    }

    def validate(self) -> None:
        if not isinstance(self.discriminator, bool):
            raise LoosefitInputError(
                "TrainDetailConfig", "discriminator", "true or false", repr(self.discriminator)
            )
        for name in ("epochs", "batch_size", "checkpoint_every"):
            v = getattr(self, name)
            if not (isinstance(v, int) and v >= 1):
                raise LoosefitInputError("TrainDetailConfig", name, "an integer >= 1", v)


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
    decoded, codes, target, clips = [], [], [], []
    for label, m, v in clip_versions(reader, split, max_frames, mirror):
        t0 = time.perf_counter()
        result = model.animate(m, stages=MOTION_ONLY)
        H, p, _ = motion_root_frames(m, model.floor_height, model.rollout_config)
        decoded.append(to_root_frame(torch.from_numpy(result.vertices), H, p))
        target.append(to_root_frame(torch.as_tensor(np.asarray(v, np.float32)), H, p))
        codes.append(torch.from_numpy(result.codes))
        clips.append(label)
        log(f"rolled out {label}: {m.num_frames} frames in {time.perf_counter() - t0:.1f} s")
    return DetailPairs(torch.cat(decoded), torch.cat(codes), torch.cat(target), clips)


# -- the stage -------------------------------------------------------------------------------


class DetailTrainer(Trainer):
    """The detail module's training: the frozen motion stage's rollouts as pairs, a
    discriminator step and a generator step per batch, held-out rollouts with and without
    the module."""

    label = "train detail"

    def __init__(
        self,
        reader: DatasetReader,
        model: AnimationModel,
        fingerprints: dict,
        mpath: Path,
        generative: str | Path | None,
        config: TrainDetailConfig,
        *,
        run: Run,
        mirror: bool,
    ):
        self.config, self.run, self.reader = config, run, reader
        self.motion, self.mpath, self.generative = model, mpath, generative
        self.sampling = torch.Generator().manual_seed(config.seed)  # every draw of the loop
        # 1. the pairs: the frozen motion stage's rollouts of the training clips (cached)
        path = run.out / "pairs.pt"
        if path.is_file():
            saved = torch.load(path, weights_only=True)
            self.pairs = DetailPairs(
                saved["decoded"], saved["codes"], saved["target"], saved["clips"]
            )
        else:
            self.pairs = rollout_pairs(model, reader, "train", mirror, config.max_frames, run.log)
            save_atomic(asdict(self.pairs), path)
        run.log(f"{len(self.pairs.codes)} training pairs from {len(self.pairs.clips)} rollouts")
        # 2. the networks
        t, dev = model.template, config.device
        self.model = DetailGenerator(t.faces, t.num_vertices, model.encoder.latent, config.model)
        self.model.to(dev)
        self.disc = MultiScaleDiscriminator(model.generative.config.uv_size, config.model).to(dev)
        self.uv = model.generative.uv
        self.lap = Laplacian(t.faces, t.num_vertices).to(dev)
        self.edges = torch.from_numpy(unique_edges(t.faces)[0]).t().to(dev)  # (2, E) each once
        self.opt_g, self.opt_d = adam(self.model, config), adam(self.disc, config)
        self.states = {
            "model": self.model,
            "discriminator": self.disc,
            "optimizer": self.opt_g,
            "optimizer_discriminator": self.opt_d,
        }
        self.meta = {
            "model_config": asdict(config.model),
            "config": config.to_dict(),
            "fingerprints": fingerprints,
            "motion_checkpoint": {
                "relative": os.path.relpath(mpath, run.out.resolve()),
                "absolute": str(mpath),
            },
            "dataset": str(Path(reader.root).resolve()),
        }

    def read_checkpoint(self, path: Path) -> dict:
        return read_checkpoint_file(path, DETAIL_FORMAT, self.config.device)

    def warm_start(self, path: str) -> None:
        saved = read_checkpoint_file(path, DETAIL_FORMAT, self.config.device)
        load_weights(self.model, saved["model"], Path(path), "this detail configuration")
        if "discriminator" in saved:
            load_weights(
                self.disc, saved["discriminator"], Path(path), "this discriminator configuration"
            )

    def checkpoint_fields(self) -> dict:
        return {"format": DETAIL_FORMAT, **self.meta}

    def train_epoch(self, epoch: int, net, bar) -> tuple[dict, dict]:
        """Batches of pairs in a random order: per batch a discriminator step on Eq. 14,
        then a generator step on Eq. 13 and its side of Eq. 14."""
        cfg, dev, cl, pairs = self.config, self.config.device, self.config.loss, self.pairs
        self.model.train()
        self.disc.train()
        N = len(pairs.codes)
        order = torch.randperm(N, generator=self.sampling)
        sums: dict[str, float] = {}
        steps = 0
        for b in range(0, N, cfg.batch_size):
            idx = order[b : b + cfg.batch_size]
            v = pairs.decoded[idx].to(dev)  # (B, V, 3): data, no gradient into the motion stage
            z, target = pairs.codes[idx].to(dev), pairs.target[idx].to(dev)
            final = v + net(v, z)
            position, laplacian = detail_geometry_loss(
                final, target, self.lap, cl.length_scale, cl.laplacian
            )
            terms = {"position": position, "laplacian": laplacian}
            loss = position + laplacian
            if cl.edge > 0:
                edge = edge_length_loss(final, target, self.edges, cl.length_scale)
                terms["edge"] = cl.edge * edge
                loss = loss + terms["edge"]
            if cfg.discriminator:
                fake, real = self.uv.encode(final), self.uv.encode(target)  # (B, 3, H, W)
                d_loss = lsgan_discriminator_loss(self.disc(real), self.disc(fake.detach()))
                self.opt_d.zero_grad(set_to_none=True)
                d_loss.backward()
                self.opt_d.step()
                g_adv = lsgan_generator_loss(self.disc(fake))
                loss = loss + cl.adversarial * g_adv
                terms.update(discriminator=d_loss, adversarial=g_adv)
            self.opt_g.zero_grad(set_to_none=True)
            loss.backward()
            self.opt_g.step()
            terms["total"] = loss
            steps += 1
            for k, val in terms.items():
                sums[k] = sums.get(k, 0.0) + float(val.detach())
            bar.set_postfix(
                step=f"{steps}/{-(-N // cfg.batch_size)}", l1=f"{sums['position'] / steps:.3f}"
            )
        return epoch_means(sums, steps), {}

    def report(self, common: dict, writer, epoch: int, history: list) -> dict:
        """The held-out clips before and after the module (no collision handling)."""
        path = self.run.out / "model.pt"
        weights = {k: v.half() for k, v in self.model.state_dict().items()}
        save_atomic({"format": DETAIL_FORMAT, **self.meta, "model": weights, "epoch": epoch}, path)
        trained = load_detail_model(path, self.mpath, self.generative, self.config.device)
        with_detail = Stages(detail=True, lengths=False, collision=False)
        test = {"surface": False}
        return {
            "discriminator": self.config.discriminator,
            "dataset": common["dataset"],
            "motion": str(self.mpath),
            "epochs": common["epochs"],
            "pairs": len(self.pairs.codes),
            **common,
            "history": history,
            "test_without": evaluate_rollouts(
                trained, self.reader, "test", stages=MOTION_ONLY, **test
            ),
            "test_with": evaluate_rollouts(
                trained, self.reader, "test", stages=with_detail, **test
            ),
        }

    def format_report(self, report: dict) -> str:
        return format_report(report)


def train_detail(
    data: str | Path,
    motion: str | Path,
    out: str | Path,
    config: TrainDetailConfig,
    generative: str | Path | None = None,
    *,
    log=print,
    progress: bool = True,
) -> dict:
    """Train (or resume) the detail module on a frozen motion stage's rollouts.

    Args:
        data: the dataset the motion stage was trained on.
        motion: the motion stage's checkpoint (``model.pt``; frozen here).
        out: the run folder (:class:`~loosefit.train.loop.Run`): a run of this configuration
            there resumes, a run of another is refused.
        config: the run.
        generative: the generative checkpoint, if not the one the motion stage records.
        log, progress: where progress lines go; whether to show a tqdm bar.

    Returns:
        The report (also ``out/report.json`` and ``out/report.md``).
    """
    reader = DatasetReader(data)
    dataset = str(Path(data).resolve())
    mpath = Path(motion).resolve()
    model = load_animation_model(mpath, generative, config.device)
    if not same_garment(model.template, reader.template):
        raise LoosefitInputError(
            reader.root, "template", f"the garment {mpath.name} was trained on", "another garment"
        )
    mirror = config.mirror
    if mirror is None:  # as the motion stage was trained (a packaged one: not mirrored)
        trained = training_config(mpath)
        mirror = bool(trained is not None and trained.mirror)
    fingerprints = stage_fingerprints(model)
    stored = {"dataset": dataset, "motion": fingerprints["motion"], "train": config.to_dict()}
    run = Run.open(out, stored, config.seed, log, progress)
    stage = DetailTrainer(
        reader, model, fingerprints, mpath, generative, config, run=run, mirror=mirror
    )
    return train(stage, run, dataset)


def format_report(report: dict) -> str:
    """A Markdown summary of a detail run's report."""
    a, b = report["test_without"], report["test_with"]
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
            cost_line(report, "generator parameters", digits=1),
            "",
        ]
    )
