"""Training the dynamic motion encoder (paper 3.3, Eqs. 10-12) on a frozen generative model.

A run is a folder of the training scaffold (:mod:`loosefit.train.loop`: ``config.json``,
``checkpoint.pt`` written atomically, TensorBoard events, ``report.json/.md``) plus
``model.pt``: the trained encoder alone, half precision, for sharing, and
``rest_state.npy``: the garment's settled drape, where every rollout starts, when the
data set does not hold it (``rest_drape.npy``, written by the simulator) and it was not
given: settled once by a function the caller passes in (the command line passes
:func:`~loosefit.sim.rest_drape.settled_rest_drape`; training itself runs no simulator).

**The previous state.** At inference a rollout feeds the encoder its own
outputs for thousands of frames, while ground-truth previous frames (teacher
forcing) are all that training would see by default: the classic exposure
bias, whose errors compound into drift. Training therefore runs the very
timeline of a rollout (rest frames, blend, motion; the garment starting from
its settled drape) clip by clip in windows of ``window`` frames (truncated
backpropagation through time: the GRU state and the previous garment carry
over between windows, detached), and the previous state of each frame is the
ground truth with probability ``p`` and the encoder's own last prediction
otherwise (scheduled sampling, Bengio et al. 2015). ``p`` falls linearly from
``teacher_start`` to ``teacher_end`` (default 0: the rest of training is pure
rollout) over the first ``teacher_fraction`` of the epochs.
``previous="teacher"`` keeps ``p = 1`` (for comparison). By default the
previous state is an input, never differentiated through; ``unroll=True``
keeps the encoder's own predictions in the graph within a window, so the loss
of a frame also trains the predictions that fed it (unrolled training, as for
learned simulators).

**Devices and processes.** A batch is stacked once and moved to ``device``; the
random draws (the clip order, the teacher choices, the noise on previous states)
come from one CPU generator and are moved there, so a CUDA run draws what a CPU
run does. Under ``torchrun`` the clips of every batch are shared among the
processes (the encoder wrapped in DDP): each draw is made for the whole batch, in
the order one process makes it, and each process keeps its clips' part; a
window's loss is a mean over the valid (clip, frame) pairs of the whole batch,
whose count the clips' lengths give, so each process divides its sums by that
count and one process or several follow the same loss curve. Only the first
process writes files and evaluates.

**Precision.** ``precision="bf16"`` runs the encoder and the frozen decoders
under ``torch.autocast`` to bfloat16 (convolutions, linear layers and the GRU;
the weights stay float32); the codes, garments and GRU state are cast to float32
as they come out, so the previous states carried on, the loss terms, the
Laplacian, the squared errors and the optimiser are float32 as with the default
``"fp32"``. Held-out evaluation always runs in float32.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import ClassVar

import numpy as np
import torch

from loosefit.data.format import DatasetReader
from loosefit.errors import LoosefitInputError
from loosefit.eval.rollouts import evaluate_rollouts
from loosefit.garment.mesh_checks import hem_loop
from loosefit.geometry.laplacian import Laplacian
from loosefit.inference.animator import AnimationModel, load_animation_model
from loosefit.inference.checkpoints import (
    MOTION_FORMAT,
    garment_record,
    half_weights,
    load_generative,
    load_weights,
    model_fingerprint,
    read_checkpoint_file,
    save_atomic,
)
from loosefit.inference.stages import MOTION_ONLY
from loosefit.inference.timeline import RolloutConfig
from loosefit.model.generative import GarmentGenerativeModel
from loosefit.model.losses import (
    ClothStructure,
    active_terms,
)
from loosefit.model.motion_encoder import DynamicMotionEncoder, MotionEncoderConfig
from loosefit.train.clips import (
    feature_statistics,
    prepare_clips,
    rollout_evaluation,
)
from loosefit.train.common import (
    barrier,
    check_device_precision,
    check_precision,
    epoch_means,
    optimizer_step,
)
from loosefit.train.loop import Run, Trainer, TrainerConfig, adam, cost_line, train
from loosefit.train.motion_window import MotionLossConfig, run_window, share_batch

CHECKPOINT_FORMAT = MOTION_FORMAT


@dataclass
class TrainMotionConfig(TrainerConfig):
    """One training run of the dynamic motion encoder (the shared fields:
    :class:`TrainerConfig`; what the options beyond the paper do and why:
    docs/design/notes/train_motion.md)."""

    epochs: int = 300  # the paper's
    batch_size: int = 1  # clips run side by side
    checkpoint_every: int = 5  # epochs
    model: MotionEncoderConfig = field(default_factory=MotionEncoderConfig)  # the encoder
    loss: MotionLossConfig = field(default_factory=MotionLossConfig)  # Eqs. 10-12's weights
    rollout: RolloutConfig = field(default_factory=RolloutConfig)  # the timeline of a clip
    window: int = 50  # frames of truncated backpropagation through time
    grad_clip: float = 10.0  # max gradient norm per step
    previous: str = "scheduled"  # "scheduled" (sampling, see the module) or "teacher"
    teacher_start: float = 1.0  # probability of a ground-truth previous state at epoch 0
    teacher_fraction: float = 0.5  # ... falling to teacher_end over this fraction of the epochs
    teacher_end: float = 0.0  # ... and staying there for the rest of training
    unroll: bool = False  # differentiate through the encoder's own predictions in a window
    mirror: bool = False  # also train on every training clip mirrored left-right
    previous_noise: float = 0.0  # m, std of noise on a ground-truth previous state; 0: none
    eval_every: int = 10  # epochs; held-out rollout errors into TensorBoard
    precision: str = "fp32"  # the forward passes': "fp32", or "bf16" (autocast; see the module)
    init: str | None = None  # warm start: a motion checkpoint of this encoder's configuration

    # ``full``: the paper's (300 epochs, batch 1, lr 1e-4); ``cpu``: up to 16 clips side by
    # side with a 10x learning rate (1e-3) for 60 epochs (why: docs/design/notes/
    # train_motion.md); ``previous_state`` and ``joints`` overrides go to the encoder.
    PRESETS: ClassVar[dict[str, dict]] = {
        "full": {},
        "cpu": {
            "epochs": 60,
            "batch_size": 16,
            "lr": 1.0e-3,
            "checkpoint_every": 2,
            "eval_every": 10,
        },
    }

    def validate(self) -> None:
        check_precision("TrainMotionConfig", self.precision)
        if self.previous not in ("scheduled", "teacher"):
            raise LoosefitInputError(
                "TrainMotionConfig", "previous", "scheduled or teacher", repr(self.previous)
            )
        if not (0.0 <= self.teacher_end <= self.teacher_start <= 1.0):
            raise LoosefitInputError(
                "TrainMotionConfig",
                "teacher_start, teacher_end",
                "0 <= teacher_end <= teacher_start <= 1",
                (self.teacher_start, self.teacher_end),
            )
        for name in ("unroll", "mirror"):
            if not isinstance(getattr(self, name), bool):
                raise LoosefitInputError(
                    "TrainMotionConfig", name, "true or false", repr(getattr(self, name))
                )
        if not self.previous_noise >= 0:
            raise LoosefitInputError(
                "TrainMotionConfig", "previous_noise", "metres >= 0", self.previous_noise
            )
        if not (isinstance(self.window, int) and self.window >= 1):
            raise LoosefitInputError("TrainMotionConfig", "window", "an integer >= 1", self.window)

    def teacher_probability(self, epoch: int) -> float:
        """The chance of a ground-truth previous state during epoch ``epoch`` (0-based)."""
        if self.previous == "teacher":
            return 1.0
        span = self.teacher_fraction * self.epochs
        if span <= 0 or epoch >= span:
            return float(self.teacher_end)
        a, b = self.teacher_start, self.teacher_end
        return float(a + (b - a) * epoch / span)


# -- the evaluation: held-out rollouts (loosefit.eval.rollouts) ------------------------------


def format_report(report: dict) -> str:
    """A Markdown summary of a run's report."""
    t = report["test"]
    hs = list(t["horizons"])
    lines = [
        f"# Dynamic motion encoder ({'with' if report['previous_state'] else 'w/o'} previous "
        f"state), {report['epochs']} epochs",
        "",
        "Rollouts of the held-out clips from their first frame; lengths in centimetres.",
        "",
        "| clip | frames | RMSE | "
        + " | ".join(f"iter-{h}" for h in hs)
        + " | Hausdorff | STED | rollout fps |",
        "|---|---:|---:|" + "---:|" * len(hs) + "---:|---:|---:|",
    ]
    for name, c in t["clips"].items():
        cells = [f"{c['horizons'][h]:.3f}" if h in c["horizons"] else "-" for h in hs]
        lines.append(
            f"| {name} | {c['frames']} | {c['rmse_cm']:.3f} | "
            + " | ".join(cells)
            + f" | {c['hausdorff_cm']:.3f} | {c['sted']:.4f} | "
            f"{c['frames_per_second']:.0f} |"
        )
    lines += [
        "",
        cost_line(report, digits=1),
        "",
    ]
    return "\n".join(lines)


# -- the stage ---------------------------------------------------------------------------------


class MotionTrainer(Trainer):
    """The motion encoder's training on a frozen generative model: its clips, its windows,
    its rollout evaluation."""

    label = "train motion encoder"
    # the encoder runs once per frame before a window's backward: DDP's hooks fire once per
    # weight; its buffers are fixed, no need to broadcast them at every frame
    ddp_buffers = False
    tags: ClassVar[dict[str, str]] = {"teacher": "train/teacher_probability"}

    def __init__(
        self,
        reader: DatasetReader,
        generative: GarmentGenerativeModel,
        gmeta: dict,
        config: TrainMotionConfig,
        run: Run,
        *,
        rest_state: torch.Tensor | None,
        settle: Callable[[DatasetReader, float], torch.Tensor] | None = None,
    ):
        self.config, self.run, self.reader = config, run, reader
        self.generative, self.gmeta = generative, gmeta
        self.template = template = reader.template
        self.device = device = torch.device(config.device)
        self.sampling = torch.Generator().manual_seed(config.seed)  # every draw of the loop
        # 1. the clips, their codes, and the drape every rollout starts from
        self.floor = floor = float(reader.body["floor_height"])
        t0 = time.perf_counter()
        self.clips = clips = prepare_clips(
            reader,
            "train",
            generative,
            floor,
            config.rollout,
            max_frames=config.max_frames,
            mirror=config.mirror,
            joints=config.model.joints,
            contacts=config.loss.collision > 0,
        )
        self.fps = clips[0].motion.fps
        rest = self.rest_drape(rest_state, settle)
        run.log(
            f"prepared {len(clips)} train clips ({sum(c.length for c in clips)} frames) "
            f"in {time.perf_counter() - t0:.1f} s"
        )
        F, mean, std = feature_statistics(reader, clips, config.model.joints)
        # 2. the encoder and what its loss reads
        self.model = DynamicMotionEncoder(generative, F, config.model, mean, std).to(device)
        self.lap = Laplacian(template.faces, template.num_vertices).to(device)
        self.structure = ClothStructure.from_template(template).to(device)
        self.hem = torch.from_numpy(hem_loop(template.vertices, template.faces)).to(device)
        self.optim = adam(self.model, config)
        self.states = {"model": self.model, "optimizer": self.optim}
        self.joint_names = tuple(clips[0].motion.joint_names)
        self.meta = {
            "model_config": {"encoder": asdict(config.model), "rollout": asdict(config.rollout)},
            "config": config.to_dict(),
            "generative": gmeta,
            "garment": garment_record(template),
            "num_features": F,
            "joint_names": list(self.joint_names),
            "floor_height": floor,
            "fps": self.fps,
            "body": dict(reader.body),
            "rest_state": rest.numpy(),
            "cloth": reader.manifest.get("config", {}).get("cloth"),  # the physics of the data
            "physics_terms": list(active_terms(config.loss)),
            "dataset": str(Path(reader.root).resolve()),
        }
        self.rest = rest.to(device)

    def rest_drape(self, given: torch.Tensor | None, settle) -> torch.Tensor:
        """(V, 3) the settled drape: ``given``, else the data set's ``rest_drape.npy``, else
        the run folder's ``rest_state.npy``, settled once by the first process with
        ``settle(reader, fps)``.

        Raises:
            LoosefitInputError: none of these: a data set simulated before the simulator
                recorded its drape, and no way to settle it given.
        """
        if given is not None:
            return torch.as_tensor(given).float()
        drape = self.reader.rest_drape
        if drape is not None:
            return torch.from_numpy(drape)
        path = self.run.out / "rest_state.npy"
        if not path.is_file() and settle is None:
            raise LoosefitInputError(
                self.reader.root / "rest_drape.npy",
                "<file>",
                "the garment settled on the rest pose, where rollouts start",
                "missing (a data set simulated before the simulator wrote it)",
                hint="pass rest_state=, or settle=loosefit.sim.rest_drape.settled_rest_drape "
                "(what `loosefit train motion` does)",
            )
        if self.run.main and not path.is_file():
            np.save(path, settle(self.reader, self.fps).numpy())
        barrier()
        return torch.from_numpy(np.load(path, allow_pickle=False))

    def read_checkpoint(self, path: Path) -> dict:
        return read_checkpoint_file(path, MOTION_FORMAT, self.device)

    def warm_start(self, path: str) -> None:
        F = self.meta["num_features"]
        warm_start(self.model, path, self.config.model, F, self.device)

    def checkpoint_fields(self) -> dict:
        return {"format": MOTION_FORMAT, **self.meta}

    def train_epoch(self, epoch: int, net, bar) -> tuple[dict, dict]:
        """Batches of clips in a random order, each run in windows along its timeline, the
        previous state drawn per frame (the teacher probability of the epoch)."""
        cfg, device, run = self.config, self.device, self.run
        self.model.train()
        teacher = cfg.teacher_probability(epoch)
        order = torch.randperm(len(self.clips), generator=self.sampling).tolist()
        sums: dict[str, float] = {}
        steps = 0
        for b in range(0, len(order), cfg.batch_size):
            clips = [self.clips[i] for i in order[b : b + cfg.batch_size]]
            batch, part = share_batch(clips, run.rank, run.world, device)  # this process's
            n = len(part.rows)
            hidden = self.model.initial_hidden(n, device)
            previous = self.rest[None].expand(n, -1, -1).clone()  # (n, V, 3)
            L = max(c.length for c in clips)
            for start in range(0, L, cfg.window):
                window = run_window(
                    net,
                    self.generative,
                    self.lap,
                    batch,
                    start,
                    min(start + cfg.window, L),
                    hidden=hidden,
                    previous=previous,
                    teacher=teacher,
                    loss=cfg.loss,
                    generator=self.sampling,
                    noise=cfg.previous_noise,
                    unroll=cfg.unroll,
                    part=part,
                    precision=cfg.precision,
                    structure=self.structure,
                    hem=self.hem,
                )
                terms, hidden, previous = window.terms, window.hidden, window.previous
                if not terms["total"].requires_grad:
                    continue  # a window with no motion frame in the batch (all preroll)
                optimizer_step(
                    self.optim, self.model.parameters(), terms, cfg.grad_clip, sums, run.world
                )
                steps += 1
        return epoch_means(sums, steps), {"teacher": teacher}

    def evaluate_now(self, epoch: int) -> bool:
        return epoch % self.config.eval_every == 0 or epoch == self.config.epochs

    def evaluate(self, epoch: int, record: dict, write) -> dict[str, float]:
        current = AnimationModel(
            generative=self.generative,
            encoder=self.model,
            template=self.template,
            rest_state=self.rest,
            joint_names=self.joint_names,
            floor_height=self.floor,
            fps=self.fps,
            body=dict(self.reader.body),
            rollout_config=self.config.rollout,
            path=self.run.checkpoint,
        )
        return rollout_evaluation(current, self.reader, MOTION_ONLY, epoch, record, write)

    def report(self, common: dict, writer, epoch: int, history: list) -> dict:
        path = self.run.out / "model.pt"
        weights = half_weights(self.model.state_dict())  # for sharing
        save_atomic({"format": MOTION_FORMAT, **self.meta, "model": weights, "epoch": epoch}, path)
        model = load_animation_model(path, self.gmeta["absolute"], self.device)
        return {
            "previous_state": self.config.model.previous_state,
            "previous": self.config.previous,
            "dataset": common["dataset"],
            "generative": self.gmeta["absolute"],
            **common,
            "test": evaluate_rollouts(model, self.reader, "test", stages=MOTION_ONLY),
        }

    def format_report(self, report: dict) -> str:
        return format_report(report)


def train_motion(
    data: str | Path,
    generative: str | Path,
    out: str | Path,
    config: TrainMotionConfig,
    *,
    log=print,
    progress: bool = True,
    rest_state: torch.Tensor | None = None,
    settle: Callable[[DatasetReader, float], torch.Tensor] | None = None,
) -> dict:
    """Train (or resume) the dynamic motion encoder on a dataset and report rollout errors.

    Args:
        data: a dataset folder.
        generative: the trained generative model's checkpoint (frozen here).
        out: the run folder (:class:`~loosefit.train.loop.Run`): a run of this configuration
            there resumes, a run of another is refused.
        config: the run.
        log, progress: where progress lines go; whether to show a tqdm bar.
        rest_state: (V, 3) the garment's settled drape in the rest pose's root frame;
            by default the data set's (``rest_drape.npy``).
        settle: for a data set without one: ``settle(reader, fps)`` -> (V, 3), run once
            and kept in the run folder
            (:func:`~loosefit.sim.rest_drape.settled_rest_drape` settles it with the
            data set's cloth configuration).

    Returns:
        The report (also ``out/report.json`` and ``out/report.md``).
    """
    reader = DatasetReader(data)
    dataset = str(Path(data).resolve())
    device = torch.device(config.device)
    check_device_precision(config.precision, device)
    gpath = Path(generative).resolve()
    gmodel, _ = load_generative(gpath, reader.template, device)
    for prm in gmodel.parameters():
        prm.requires_grad_(False)
    gmeta = {
        "relative": os.path.relpath(gpath, Path(out).resolve()),
        "absolute": str(gpath),
        "fingerprint": model_fingerprint(gmodel),
    }
    stored = {"dataset": dataset, "generative": gmeta["fingerprint"], "train": config.to_dict()}
    run = Run.open(out, stored, config.seed, log, progress)
    stage = MotionTrainer(reader, gmodel, gmeta, config, run, rest_state=rest_state, settle=settle)
    return train(stage, run, dataset)


# -- a warm start, a run's configuration ------------------------------------------------------


def warm_start(
    encoder: DynamicMotionEncoder,
    path: str | Path,
    config: MotionEncoderConfig,
    num_features: int,
    device="cpu",
) -> None:
    """Load another motion checkpoint's encoder weights (feature statistics included) into
    ``encoder`` (fine-tuning).

    Raises:
        LoosefitInputError: not a motion checkpoint, another encoder configuration than
            ``config``, another number of motion features, or weights that do not fit.
    """
    saved = read_checkpoint_file(path, MOTION_FORMAT, device)
    recorded = (saved.get("model_config") or {}).get("encoder")
    mine = json.loads(json.dumps(asdict(config)))
    if recorded is not None and {**mine, **recorded} != mine:
        raise LoosefitInputError(
            path,
            "model_config.encoder",
            str(mine),
            str(recorded),
            hint="warm-start from an encoder of this run's configuration",
        )
    if saved.get("num_features") != num_features:
        raise LoosefitInputError(
            path,
            "num_features",
            num_features,
            saved.get("num_features"),
            hint="the same --joints as the run it starts from",
        )
    load_weights(encoder, saved["model"], Path(path), "this encoder configuration")


def training_config(path: str | Path) -> TrainMotionConfig | None:
    """The training configuration a motion-stage checkpoint records (None: a packaged one)."""
    data = read_checkpoint_file(path, MOTION_FORMAT)
    return TrainMotionConfig.from_dict(data["config"]) if "config" in data else None
