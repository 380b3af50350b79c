"""Training the garment generative model (paper 3.2, Eqs. 6-8), resumable.

The run folder, the checkpoints, resuming, logging and the report are the training
scaffold's (:mod:`loosefit.train.loop`); here are the stage's configuration, its data
(every frame of the train split in the root frame, with its unposed target), its
step and its evaluation. The checkpoint also holds the garment template, so a
trained model can be used without its dataset.

**Devices and processes.** Everything a step touches lives on ``device``; the
random draws (the batch order, the sampling noise) come from the CPU's generator
and are moved there, so a CUDA run draws what a CPU run does. Under ``torchrun``
each process takes a share of every batch (DDP averages the gradients); only the
first process writes files and evaluates.

**Precision.** ``precision="bf16"`` runs the model's forward pass under
``torch.autocast`` to bfloat16 (its convolutions and linear layers; the weights
stay float32); its outputs are cast to float32 before the loss, so the loss terms,
the Laplacian, the squared errors and the optimiser are float32 as with the
default ``"fp32"``. Evaluation always runs in float32.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import ClassVar, NamedTuple

import numpy as np
import torch

from loosefit.data.format import DatasetReader
from loosefit.errors import LoosefitInputError
from loosefit.eval.metrics import hausdorff, rmse, sted
from loosefit.geometry.inverse_skinning import InverseSkinningConfig
from loosefit.geometry.laplacian import Laplacian
from loosefit.inference.checkpoints import (
    GENERATIVE_FORMAT,
    garment_record,
    load_generative,
    read_generative,
)
from loosefit.model.generative import (
    GarmentGenerativeModel,
    GenerativeConfig,
    GenerativeLossConfig,
    GenerativeOutput,
    generative_loss,
)
from loosefit.model.losses import ClothStructure, active_terms
from loosefit.train.common import all_mean, autocast, check_device_precision, check_precision, shard
from loosefit.train.frames import PreparedFrames, avatar_for, prepare_split
from loosefit.train.loop import Run, Trainer, TrainerConfig, adam, cost_line, train
from loosefit.types import GarmentTemplate

CHECKPOINT_FORMAT = GENERATIVE_FORMAT


@dataclass
class TrainGenerativeConfig(TrainerConfig):
    """One training run of the generative model (the shared fields: :class:`TrainerConfig`)."""

    epochs: int = 500  # the paper's
    batch_size: int = 56  # frames per step, the paper's
    checkpoint_every: int = 10  # epochs
    model: GenerativeConfig = field(default_factory=GenerativeConfig)  # the networks
    loss: GenerativeLossConfig = field(default_factory=GenerativeLossConfig)  # Eqs. 6-8
    skinning: InverseSkinningConfig = field(default_factory=InverseSkinningConfig)  # unposing
    laplacian: str = "uniform"  # mesh Laplacian of Eq. 6: "uniform" or "cotangent"
    ssdr_iterations: int = 30  # decoder "ssdr": Dem Bones iterations
    eval_every: int = 50  # epochs; test-split error into TensorBoard
    precision: str = "fp32"  # the forward pass's: "fp32", or "bf16" (autocast; see the module)
    init: str | None = None  # warm start: a generative checkpoint of this garment and model
    mirror: bool = False  # also every training frame mirrored left-right (the garment symmetric)

    # ``full``: the paper's (a GPU, 500 epochs); ``cpu``: 64x64 UV maps, narrower convolutions
    # and a 10x larger learning rate (1e-3), everything else the paper's (why:
    # docs/design/notes/train_generative.md)
    PRESETS: ClassVar[dict[str, dict]] = {
        "full": {"model": GenerativeConfig(uv_size=128)},
        "cpu": {
            "model": GenerativeConfig(
                uv_size=64, channels=(16, 32, 64, 128), rec_hidden=(256, 512, 512)
            ),
            "epochs": 300,
            "lr": 1.0e-3,
            "checkpoint_every": 10,
            "eval_every": 50,
        },
    }

    def validate(self) -> None:
        check_precision("TrainGenerativeConfig", self.precision)


# -- the data: the train split's frames (loosefit.train.frames); the ssdr decoder's start


def _ssdr_init(frames: PreparedFrames, template: GarmentTemplate, cfg: TrainGenerativeConfig):
    from loosefit.model.ssdr import SSDRConfig, decompose

    d = decompose(
        frames.posed.numpy(),
        template.vertices,
        SSDRConfig(bones=cfg.model.ssdr_bones, iterations=cfg.ssdr_iterations, seed=cfg.seed),
        faces=template.faces,
    )
    return d.rest, d.weights, d.transforms.mean(0)


def _basis_init(frames: PreparedFrames, cfg: TrainGenerativeConfig):
    """Decoder "basis": the principal directions of the training frames (root frame).

    Raises:
        LoosefitInputError: fewer training frames than directions asked for.
    """
    from loosefit.model.engine import fit_basis

    K, N = cfg.model.basis_size, len(frames)
    if N < K:
        raise LoosefitInputError(
            "--basis-size",
            "basis_size",
            f"at most the {N} training frames (each clip's mirror image counts with --mirror)",
            K,
        )
    b = fit_basis(frames.posed, K)
    return b.mean, b.basis, b.scale


# -- the step ---------------------------------------------------------------------------------


def _float32(out: GenerativeOutput) -> GenerativeOutput:
    """The model's output with every tensor in float32 (after a bf16 forward pass)."""
    values = {f.name: getattr(out, f.name) for f in fields(out)}
    return GenerativeOutput(**{k: None if v is None else v.float() for k, v in values.items()})


# -- the evaluation ---------------------------------------------------------------------------


@torch.no_grad()
def reconstruct(model: GarmentGenerativeModel, frames: PreparedFrames, batch: int = 64):
    """Encode and decode (the posterior mean) every frame: (N, V, 3) root frame."""
    model.eval()
    return model.reconstruct_all(frames.posed, batch)


def evaluate(model: GarmentGenerativeModel, frames: PreparedFrames, faces: np.ndarray) -> dict:
    """Reconstruction errors of a split, in centimetres, frame-weighted over its clips.

    RMSE and Hausdorff are in the world frame (the same as in the root frame: the
    change of frame is rigid); STED per clip over consecutive frames.
    """
    pred = reconstruct(model, frames)
    index = torch.arange(len(frames))
    world_pred = frames.world(index, pred).numpy()
    world_true = frames.world(index, frames.posed).numpy()
    per_clip = {}
    for i, name in enumerate(frames.names):
        sel = (frames.clip == i).numpy()
        p, t = world_pred[sel], world_true[sel]
        per_clip[name] = {
            "frames": int(sel.sum()),
            "rmse_cm": 100 * rmse(p, t),
            "hausdorff_cm": 100 * float(hausdorff(p, t, faces).mean()),
            "sted": sted(p, t, faces)["sted"] if len(p) > 1 else 0.0,
        }
    n = np.array([c["frames"] for c in per_clip.values()], float)

    def mean(key: str) -> float:
        return float((np.array([c[key] for c in per_clip.values()]) * n).sum() / n.sum())

    return {
        "frames": int(n.sum()),
        "rmse_cm": 100 * rmse(world_pred, world_true),
        "hausdorff_cm": mean("hausdorff_cm"),
        "sted": mean("sted"),
        "clips": per_clip,
    }


def format_report(report: dict) -> str:
    """A Markdown summary of a run's report."""
    lines = [
        f"# Generative model ({report['decoder']} decoder), {report['epochs']} epochs",
        "",
        "| split | frames | RMSE (cm) | Hausdorff (cm) | STED |",
        "|---|---:|---:|---:|---:|",
    ]
    for split in ("train", "test"):
        r = report[split]
        lines.append(
            f"| {split} | {r['frames']} | {r['rmse_cm']:.3f} | "
            f"{r['hausdorff_cm']:.3f} | {r['sted']:.4f} |"
        )
    lines += [
        "",
        cost_line(report),
        "",
    ]
    return "\n".join(lines)


# -- the stage --------------------------------------------------------------------------------


class GenerativeTrainer(Trainer):
    """The generative model's training: its frames, its step, its evaluation."""

    ddp_buffers = True

    def __init__(self, reader: DatasetReader, config: TrainGenerativeConfig, run: Run):
        self.config, self.run, self.reader = config, run, reader
        self.template = template = reader.template
        self.device = device = torch.device(config.device)
        check_device_precision(config.precision, device)
        self.label = f"train {config.model.decoder}"
        # 1. the frames: the train split (with the body's contacts for the collision term)
        avatar = avatar_for(reader)
        t0 = time.perf_counter()
        self.contacts = config.loss.collision > 0
        mf = config.max_frames
        self.train = prepare_split(
            reader,
            "train",
            avatar,
            config.skinning,
            max_frames=mf,
            contacts=self.contacts,
            mirror=config.mirror,
        )
        self.test = prepare_split(reader, "test", avatar, config.skinning, max_frames=mf)
        run.log(
            f"prepared {len(self.train)} train and {len(self.test)} test frames "
            f"in {time.perf_counter() - t0:.1f} s"
        )
        # 2. the networks
        ssdr = None
        if config.model.decoder == "ssdr":
            t0 = time.perf_counter()
            ssdr = _ssdr_init(self.train, template, config)
            run.log(
                f"skinning decomposition: {config.model.ssdr_bones} bones "
                f"in {time.perf_counter() - t0:.1f} s"
            )
        basis = None
        if config.model.decoder == "basis":
            basis = _basis_init(self.train, config)
            run.log(f"linear basis: {config.model.basis_size} directions of the training frames")
        self.model = GarmentGenerativeModel(template, config.model, ssdr=ssdr, basis=basis)
        self.model.to(device)
        self.lap = Laplacian(
            template.faces, template.num_vertices, kind=config.laplacian, vertices=template.vertices
        ).to(device)
        self.optim = adam(self.model, config)
        self.states = {"model": self.model, "optimizer": self.optim}
        # 3. the tensors a step reads, on the device
        self.posed, self.unposed = self.train.posed.to(device), self.train.unposed.to(device)
        self.structure = ClothStructure.from_template(template).to(device)
        if self.contacts:
            self.points = self.train.contact_points.to(device)
            self.normals = self.train.contact_normals.to(device)

    def read_checkpoint(self, path: Path) -> dict:
        return read_generative(path, self.template, self.device)[0]

    def warm_start(self, path: str) -> None:
        warm_start(self.model, path, self.template, self.config.model, self.device)

    def checkpoint_fields(self) -> dict:
        return {
            "format": GENERATIVE_FORMAT,
            "model_config": asdict(self.config.model),
            "config": self.config.to_dict(),
            "garment": garment_record(self.template),
            "physics_terms": list(active_terms(self.config.loss)),
        }

    def train_epoch(self, epoch: int, net, bar) -> tuple[dict, dict]:
        """Batches of frames in a random order; under torchrun each process takes its share
        of every batch, and the terms summed over the processes are the batch's means."""
        cfg, device, rank, world = self.config, self.device, self.run.rank, self.run.world
        self.model.train()
        n = len(self.train)
        steps = max(1, (n + cfg.batch_size - 1) // cfg.batch_size)
        order = torch.randperm(n)
        sums: dict[str, float] = {}
        for s in range(steps):
            idx = order[s * cfg.batch_size : (s + 1) * cfg.batch_size].to(device)
            # the whole batch's noise, from the CPU's generator on every device
            noise = torch.randn(len(idx), self.model.config.latent).to(device)
            mine, share = shard(len(idx), rank, world)  # this process's part, its weight
            mine = mine.to(device)
            with autocast(cfg.precision, device):
                out = net(self.posed[idx[mine]], noise=noise[mine])
            rows = idx[mine]
            touch = (self.points[rows], self.normals[rows]) if self.contacts else None
            terms = generative_loss(
                _float32(out),
                self.posed[rows],
                self.unposed[rows],
                self.model.template,
                self.lap,
                cfg.loss,
                structure=self.structure,
                contacts=touch,
            )
            self.optim.zero_grad(set_to_none=True)
            (terms["total"] * share * world).backward()  # DDP averages: the batch's mean
            self.optim.step()
            for k, v in all_mean({k: v.detach() * share for k, v in terms.items()}).items():
                sums[k] = sums.get(k, 0.0) + v / steps
        return sums, {}

    def evaluate_now(self, epoch: int) -> bool:
        return epoch % self.config.eval_every == 0 and epoch < self.config.epochs  # last: report

    def evaluate(self, epoch: int, record: dict, write) -> dict[str, float]:
        err = evaluate(self.model, self.test, self.template.faces)
        return {"test/rmse_cm": err["rmse_cm"], "test/hausdorff_cm": err["hausdorff_cm"]}

    def report(self, common: dict, writer, epoch: int, history: list) -> dict:
        test = evaluate(self.model, self.test, self.template.faces)
        writer.add_scalar("test/rmse_cm", test["rmse_cm"], epoch)
        writer.add_scalar("test/hausdorff_cm", test["hausdorff_cm"], epoch)
        writer.flush()
        return {
            "decoder": self.config.model.decoder,
            **common,
            "train": evaluate(self.model, self.train, self.template.faces),
            "test": test,
        }

    def format_report(self, report: dict) -> str:
        return format_report(report)


def train_generative(
    data: str | Path,
    out: str | Path,
    config: TrainGenerativeConfig,
    log=print,
    progress: bool = True,
) -> dict:
    """Train (or resume) a generative model on a dataset and report its errors.

    Args:
        data: a dataset folder (``loosefit simulate``).
        out: the run folder (:class:`~loosefit.train.loop.Run`): a run of this configuration
            there resumes, a run of another is refused.
        config: the run.
        log, progress: where progress lines go; whether to show a tqdm bar.

    Returns:
        The report (also written to ``out/report.json`` and ``out/report.md``).
    """
    reader = DatasetReader(data)
    dataset = str(Path(data).resolve())
    run = Run.open(out, {"dataset": dataset, "train": config.to_dict()}, config.seed, log, progress)
    return train(GenerativeTrainer(reader, config, run), run, dataset)


# -- a run's checkpoint, a warm start ---------------------------------------------------------


class GenerativeCheckpoint(NamedTuple):
    """A generative run's checkpoint as :func:`load_checkpoint` reads it."""

    model: GarmentGenerativeModel  # in eval mode
    config: TrainGenerativeConfig  # the run's training configuration
    data: dict  # the raw checkpoint


def load_checkpoint(
    path: str | Path, template: GarmentTemplate | None = None, device="cpu"
) -> GenerativeCheckpoint:
    """A generative run's checkpoint: the model and its training configuration.

    Args:
        path: the ``checkpoint.pt`` of a run.
        template: if given, the garment the model must have been trained on.
        device: where to put the model.

    Returns:
        :class:`GenerativeCheckpoint`: the model in eval mode, its
        :class:`TrainGenerativeConfig`, the raw checkpoint dict.

    Raises:
        LoosefitInputError: not a generative-model checkpoint, another garment, weights
            that do not fit, or no training configuration (a packaged ``generative.pt``:
            :func:`~loosefit.inference.checkpoints.load_generative` reads those).
    """
    model, data = load_generative(path, template, device)
    if "config" not in data:
        raise LoosefitInputError(
            path,
            "config",
            "a training run's configuration",
            "none (a packaged model)",
            hint="load it with loosefit.inference.checkpoints.load_generative",
        )
    return GenerativeCheckpoint(model, TrainGenerativeConfig.from_dict(data["config"]), data)


def warm_start(
    model: GarmentGenerativeModel,
    path: str | Path,
    template: GarmentTemplate,
    config: GenerativeConfig,
    device="cpu",
) -> None:
    """Load another generative checkpoint's weights into ``model`` (fine-tuning).

    Raises:
        LoosefitInputError: not a generative checkpoint, another garment than
            ``template``'s, or another model configuration than ``config``.
    """
    source, data = load_generative(path, template, device)
    mine, theirs = (json.loads(json.dumps(asdict(c))) for c in (config, source.config))
    if mine != theirs:
        raise LoosefitInputError(
            path,
            "model_config",
            str(mine),
            str(theirs),
            hint="warm-start from a model of this run's --preset and --decoder",
        )
    model.load_state_dict(source.state_dict())
