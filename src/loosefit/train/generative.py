"""Training the garment generative model (paper 3.2, Eqs. 6-8), resumable.

A run is a folder::

    config.json         the run's configuration (a rerun with another one is refused)
    checkpoint.pt       model, optimizer, epoch, RNG states: written atomically
                        every ``checkpoint_every`` epochs and at the end
    events.*            TensorBoard logs (losses per epoch, errors per evaluation)
    report.json/.md     the final reconstruction errors on the train and test splits

Killing a run and starting the same command again resumes from the last
checkpoint. The checkpoint also holds the garment template, so a trained model
can be used without its dataset.

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
import resource
import time
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import numpy as np
import torch

from loosefit.data.format import DatasetReader, write_json_atomic
from loosefit.errors import LoosefitInputError
from loosefit.eval.metrics import hausdorff, rmse, sted
from loosefit.geometry.inverse_skinning import InverseSkinningConfig
from loosefit.geometry.laplacian import Laplacian
from loosefit.inference.checkpoints import (
    GENERATIVE_FORMAT,
    garment_record,
    load_generative,
    read_generative,
    save_atomic,
)
from loosefit.model.generative import (
    GarmentGenerativeModel,
    GenerativeConfig,
    GenerativeLossConfig,
    GenerativeOutput,
    generative_loss,
)
from loosefit.model.physics import ClothStructure, active_terms
from loosefit.train.common import (
    all_mean,
    apply_overrides,
    autocast,
    barrier,
    check_device_precision,
    check_precision,
    distributed,
    machine,
    open_run,
    restore_training,
    shard,
)
from loosefit.train.frames import PreparedFrames, avatar_for, prepare_split
from loosefit.types import GarmentTemplate

CHECKPOINT_FORMAT = GENERATIVE_FORMAT


@dataclass
class TrainGenerativeConfig:
    """One training run of the generative model."""

    model: GenerativeConfig = field(default_factory=GenerativeConfig)
    loss: GenerativeLossConfig = field(default_factory=GenerativeLossConfig)
    skinning: InverseSkinningConfig = field(default_factory=InverseSkinningConfig)
    epochs: int = 500
    batch_size: int = 56
    lr: float = 1.0e-4
    weight_decay: float = 1.0e-3  # Adam's (L2) weight decay, as the paper
    laplacian: str = "uniform"  # mesh Laplacian of Eq. 6: "uniform" or "cotangent"
    ssdr_iterations: int = 30  # decoder "ssdr": Dem Bones iterations
    checkpoint_every: int = 10  # epochs
    eval_every: int = 50  # epochs; test-split error into TensorBoard
    max_frames: int | None = None  # per clip, for quick runs
    seed: int = 0
    device: str = "cpu"
    precision: str = "fp32"  # the forward pass's: "fp32", or "bf16" (autocast; see the module)
    # warm start: a generative checkpoint (a run's or a packaged generative.pt) of the same
    # garment and model configuration whose weights the run starts from (a fresh optimiser)
    init: str | None = None

    def __post_init__(self) -> None:
        check_precision("TrainGenerativeConfig", self.precision)

    @classmethod
    def preset(cls, name: str, **overrides) -> TrainGenerativeConfig:
        """``full``: the paper's (a GPU, 500 epochs); ``cpu``: a useful model in ~20 CPU minutes.

        ``cpu`` uses 64x64 UV maps, narrower convolutions and a 10x larger learning
        rate (1e-3) so that a few hundred epochs of the small ``demo`` data converge;
        everything else is the paper's.
        """
        model_overrides = {k: overrides.pop(k) for k in ("decoder",) if k in overrides}
        if name == "full":
            cfg = cls(model=GenerativeConfig(uv_size=128, **model_overrides))
        elif name == "cpu":
            cfg = cls(
                model=GenerativeConfig(
                    uv_size=64,
                    channels=(16, 32, 64, 128),
                    rec_hidden=(256, 512, 512),
                    **model_overrides,
                ),
                epochs=300,
                lr=1.0e-3,
                checkpoint_every=10,
                eval_every=50,
            )
        else:
            raise LoosefitInputError("--preset", "preset", "full or cpu", repr(name))
        apply_overrides(cfg, overrides).__post_init__()
        return cfg

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> TrainGenerativeConfig:
        d = dict(d)
        d["model"] = GenerativeConfig(**d["model"])
        d["loss"] = GenerativeLossConfig(**d["loss"])
        d["skinning"] = InverseSkinningConfig(**d["skinning"])
        return cls(**d)


# -- checkpoints -----------------------------------------------------------------


def save_checkpoint(
    path: Path,
    model: GarmentGenerativeModel,
    template: GarmentTemplate,
    config: TrainGenerativeConfig,
    **state,
) -> None:
    """Write a checkpoint atomically (a temporary file, then a rename): the model's
    configuration and weights, the garment, and the training configuration (to resume)."""
    data = {
        "format": GENERATIVE_FORMAT,
        "model_config": asdict(config.model),
        "config": config.to_dict(),
        "garment": garment_record(template),
        "model": model.state_dict(),
        "physics_terms": list(active_terms(config.loss)),
        **state,
    }
    save_atomic(data, path)


def load_checkpoint(path: str | Path, template: GarmentTemplate | None = None, device="cpu"):
    """A generative run's checkpoint: the model and its training configuration.

    Args:
        path: the ``checkpoint.pt`` of a run.
        template: if given, the garment the model must have been trained on.
        device: where to put the model.

    Returns:
        (model in eval mode, its :class:`TrainGenerativeConfig`, the raw checkpoint dict).

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
    return model, TrainGenerativeConfig.from_dict(data["config"]), data


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


# -- evaluation ---------------------------------------------------------------------


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


# -- training ------------------------------------------------------------------------


def _float32(out: GenerativeOutput) -> GenerativeOutput:
    """The model's output with every tensor in float32 (after a bf16 forward pass)."""
    values = {f.name: getattr(out, f.name) for f in fields(out)}
    return GenerativeOutput(**{k: None if v is None else v.float() for k, v in values.items()})


def _ssdr_init(frames: PreparedFrames, template: GarmentTemplate, cfg: TrainGenerativeConfig):
    from loosefit.model.ssdr import SSDRConfig, decompose

    d = decompose(
        frames.posed.numpy(),
        template.vertices,
        SSDRConfig(bones=cfg.model.ssdr_bones, iterations=cfg.ssdr_iterations, seed=cfg.seed),
        faces=template.faces,
    )
    return d.rest, d.weights, d.transforms.mean(0)


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
        out: the run folder; an existing run with the same configuration resumes.
        config: the run.
        log: where progress lines go.
        progress: show a tqdm bar.

    Returns:
        The report (also written to ``out/report.json`` and ``out/report.md``).
    """
    from torch.utils.tensorboard import SummaryWriter
    from tqdm import tqdm

    out = Path(out)
    reader = DatasetReader(data)
    template = reader.template
    ckpt_path = out / "checkpoint.pt"
    rank, world = distributed()
    main = rank == 0
    if main:
        open_run(out, {"dataset": str(Path(data).resolve()), "train": config.to_dict()})
    else:
        log, progress = (lambda *_: None), False
    barrier()

    torch.manual_seed(config.seed)
    device = torch.device(config.device)
    check_device_precision(config.precision, device)
    avatar = avatar_for(reader)
    t0 = time.perf_counter()
    contacts = config.loss.collision > 0  # the collision term's body points, per frame
    train = prepare_split(reader, "train", avatar, config.skinning, config.max_frames, contacts)
    test = prepare_split(reader, "test", avatar, config.skinning, config.max_frames)
    log(
        f"prepared {len(train)} train and {len(test)} test frames "
        f"in {time.perf_counter() - t0:.1f} s"
    )

    ssdr = None
    if config.model.decoder == "ssdr":
        t0 = time.perf_counter()
        ssdr = _ssdr_init(train, template, config)
        log(
            f"skinning decomposition: {config.model.ssdr_bones} bones "
            f"in {time.perf_counter() - t0:.1f} s"
        )
    model = GarmentGenerativeModel(template, config.model, ssdr=ssdr).to(device)
    lap = Laplacian(
        template.faces, template.num_vertices, kind=config.laplacian, vertices=template.vertices
    ).to(device)
    optim = torch.optim.Adam(model.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    epoch, history = 0, []
    if ckpt_path.is_file():
        data_, _ = read_generative(ckpt_path, template, device)
        epoch, history = restore_training(data_, {"model": model, "optimizer": optim})
        log(f"resumed {ckpt_path} at epoch {epoch}")
    elif config.init:
        warm_start(model, config.init, template, config.model, device)
        log(f"started from the weights of {config.init}")

    posed, unposed = train.posed.to(device), train.unposed.to(device)
    structure = ClothStructure.from_template(template).to(device)
    if contacts:
        points, normals = train.contact_points.to(device), train.contact_normals.to(device)
    net = model
    if world > 1:  # torchrun: each process a share of every batch, gradients averaged
        net = torch.nn.parallel.DistributedDataParallel(model)
    writer = SummaryWriter(str(out)) if main else None
    n = len(train)
    steps = max(1, (n + config.batch_size - 1) // config.batch_size)
    bar = tqdm(
        total=config.epochs,
        initial=epoch,
        desc=f"train {config.model.decoder}",
        unit="epoch",
        disable=not progress,
    )
    t_start = time.perf_counter()
    epochs_run = 0
    while epoch < config.epochs:
        model.train()
        order = torch.randperm(n)
        sums: dict[str, float] = {}
        for s in range(steps):
            idx = order[s * config.batch_size : (s + 1) * config.batch_size].to(device)
            # the whole batch's noise, from the CPU's generator on every device
            noise = torch.randn(len(idx), model.config.latent).to(device)
            mine, share = shard(len(idx), rank, world)  # this process's part, its weight
            mine = mine.to(device)
            with autocast(config.precision, device):
                out_ = net(posed[idx[mine]], noise=noise[mine])
            rows = idx[mine]
            touch = (points[rows], normals[rows]) if contacts else None
            terms = generative_loss(
                _float32(out_),
                posed[rows],
                unposed[rows],
                model.template,
                lap,
                config.loss,
                structure,
                touch,
            )
            optim.zero_grad(set_to_none=True)
            (terms["total"] * share * world).backward()  # DDP averages: the batch's mean
            optim.step()
            for k, v in all_mean({k: v.detach() * share for k, v in terms.items()}).items():
                sums[k] = sums.get(k, 0.0) + v / steps
        if not np.isfinite(sums["total"]):
            raise RuntimeError(f"training diverged at epoch {epoch + 1}: loss {sums['total']}")
        epoch += 1
        epochs_run += 1
        history.append({"epoch": epoch, **sums})
        bar.set_postfix(loss=f"{sums['total']:.3g}")
        bar.update(1)
        if not main:
            continue
        for k, v in sums.items():
            writer.add_scalar(f"loss/{k}", v, epoch)
        # the checkpoint first: a kill during an evaluation loses no training
        if epoch % config.checkpoint_every == 0 or epoch == config.epochs:
            save_checkpoint(
                ckpt_path,
                model,
                template,
                config,
                optimizer=optim.state_dict(),
                epoch=epoch,
                history=history,
                rng=torch.get_rng_state(),
            )
        if epoch % config.eval_every == 0 and epoch < config.epochs:  # the last: the report's
            err = evaluate(model, test, template.faces)
            writer.add_scalar("test/rmse_cm", err["rmse_cm"], epoch)
            writer.add_scalar("test/hausdorff_cm", err["hausdorff_cm"], epoch)
    bar.close()
    seconds = time.perf_counter() - t_start
    barrier()
    if not main:  # the report is the first process's
        return {"history": history}
    test_err = evaluate(model, test, template.faces)
    writer.add_scalar("test/rmse_cm", test_err["rmse_cm"], epoch)
    writer.add_scalar("test/hausdorff_cm", test_err["hausdorff_cm"], epoch)
    writer.flush()

    report = {
        "decoder": config.model.decoder,
        "dataset": str(Path(data).resolve()),
        "epochs": config.epochs,
        "parameters": sum(p.numel() for p in model.parameters()),
        "seconds_per_epoch": seconds / epochs_run if epochs_run else None,
        "peak_memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "machine": machine(config.device),
        "final_loss": history[-1] if history else None,
        "train": evaluate(model, train, template.faces),
        "test": test_err,
    }
    write_json_atomic(out / "report.json", report)
    (out / "report.md").write_text(format_report(report))
    writer.close()
    return report


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
    spe = report.get("seconds_per_epoch")
    lines += [
        "",
        f"{report['parameters']:,} parameters; "
        + (f"{spe:.2f} s per epoch; " if spe else "")
        + f"peak memory {report['peak_memory_mb']:.0f} MB; {report['machine']}.",
        "",
    ]
    return "\n".join(lines)
