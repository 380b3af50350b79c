"""The training scaffold every stage runs in: its configuration, its run folder, its loop.

A run is a folder::

    config.json         the run's configuration (a rerun with another one is refused)
    checkpoint.pt       networks, optimisers, epoch, loss history, RNG states: written
                        atomically every ``checkpoint_every`` epochs and at the end
    events.*            TensorBoard logs (losses per epoch, errors per evaluation)
    report.json/.md     the final errors, written only once the run is complete

Killing a run and starting the same command again resumes from the last checkpoint,
bit for bit. A stage (:class:`Trainer`) brings its data, its networks, one epoch of
training and its evaluation; :func:`train` does the rest, in this order: resume (or
warm-start), then per epoch train, log, checkpoint, evaluate; then the report.

Under ``torchrun`` (``world`` > 1) every process trains its share of each batch
(the stage's network wrapped in DDP) and only the first writes files and evaluates.
"""

from __future__ import annotations

import copy
import json
import math
import resource
import time
import typing
from dataclasses import asdict, dataclass, fields, is_dataclass, replace
from pathlib import Path

import torch

from loosefit.data.format import write_json_atomic
from loosefit.errors import LoosefitInputError
from loosefit.inference.checkpoints import save_atomic
from loosefit.train.common import barrier, distributed, machine

# -- the configuration -----------------------------------------------------------------------


@dataclass
class TrainerConfig:
    """The fields every training stage has; a stage's own dataclass adds its fields and
    redeclares a default where its own differs (the field keeps its place)."""

    epochs: int = 100  # passes over the training data
    batch_size: int = 1  # frames, pairs or clips per optimiser step (the stage says which)
    lr: float = 1.0e-4  # Adam's learning rate
    weight_decay: float = 1.0e-3  # Adam's (L2) weight decay, as the paper
    checkpoint_every: int = 5  # epochs between checkpoints (and one at the end)
    max_frames: int | None = None  # frames kept per clip, for quick runs; None: all
    seed: int = 0  # torch's seed and the seed of the stage's own random draws
    device: str = "cpu"  # where the networks and every batch live

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        """Check the fields (a stage's subclass adds its checks).

        Raises:
            LoosefitInputError: a field out of range.
        """

    # presets: name -> the fields that differ from the defaults (a stage's subclass sets it)
    PRESETS: typing.ClassVar[dict[str, dict]] = {}

    @classmethod
    def preset(cls, name: str, **overrides):
        """A preset of :attr:`PRESETS` with ``overrides`` set on it (those not None). An
        override that names a field of the ``model`` configuration (such as a decoder or a
        joint set) is set there.

        Raises:
            LoosefitInputError: an unknown preset, or an override that names no field.
        """
        if name not in cls.PRESETS:
            raise LoosefitInputError("--preset", "preset", " or ".join(cls.PRESETS), repr(name))
        cfg = cls(**copy.deepcopy(cls.PRESETS[name]))
        mine = _field_names(cls)
        given = {k: v for k, v in overrides.items() if v is not None}
        model = {k: given.pop(k) for k in list(given) if k not in mine}
        for k in model:
            if "model" not in mine or k not in _field_names(cfg.model):
                raise LoosefitInputError(cls.__name__, k, "a field of it or of its model", "none")
        if model:
            cfg.model = replace(cfg.model, **model)  # validated by the model's configuration
        for k, v in given.items():
            setattr(cfg, k, v)
        cfg.validate()
        return cfg

    def to_dict(self) -> dict:
        """The configuration as plain data (``config.json``'s ``train``, a checkpoint's)."""
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict):
        """The configuration a :meth:`to_dict` recorded; missing fields take their default
        (a run recorded before the field existed).

        Raises:
            LoosefitInputError: a key that names no field, at the top or in a nested
                configuration (``model``, ``loss``, ...).
        """
        hints = typing.get_type_hints(cls)
        _check_keys(cls, d, cls.__name__)
        values = dict(d)
        for f in fields(cls):
            kind = hints[f.name]
            if f.name in values and isinstance(kind, type) and is_dataclass(kind):
                _check_keys(kind, values[f.name], f"{cls.__name__}.{f.name}")
                values[f.name] = kind(**values[f.name])
        return cls(**values)


def _field_names(config) -> set[str]:
    return {f.name for f in fields(config)}


def _check_keys(kind: type, d: dict, where: str) -> None:
    """Refuse a key of ``d`` that names no field of the dataclass ``kind``."""
    names = _field_names(kind)
    for key in d:
        if key not in names:
            raise LoosefitInputError(where, key, f"a field of {kind.__name__}", "unknown key")


# -- the run folder --------------------------------------------------------------------------

# Training fields added after runs were recorded without them, with the value such runs
# had: their folders still resume (and rerun scripts still pass over them).
ADDED_FIELDS = {"precision": "fp32", "init": None}
# the same for the loss's fields (the physics terms: runs recorded before had them off)
ADDED_LOSS_FIELDS = {
    "membrane": 0.0,
    "bending": 0.0,
    "collision": 0.0,
    "collision_epsilon": 0.002,
    "flare": 0.0,
}


def open_run(out: Path, stored: dict) -> None:
    """Create a run folder or check that it holds a run of the same configuration (a
    recorded ``train`` configuration without a field of :data:`ADDED_FIELDS` had its value).

    Raises:
        LoosefitInputError: ``out/config.json`` records another configuration.
    """
    out.mkdir(parents=True, exist_ok=True)
    cfg_path = out / "config.json"
    if cfg_path.is_file():
        recorded, current = json.loads(cfg_path.read_text()), json.loads(json.dumps(stored))
        if isinstance(recorded.get("train"), dict) and isinstance(current.get("train"), dict):
            added = {k: v for k, v in ADDED_FIELDS.items() if k in current["train"]}
            recorded["train"] = {**added, **recorded["train"]}
            loss, now = recorded["train"].get("loss"), current["train"].get("loss")
            if isinstance(loss, dict) and isinstance(now, dict):
                added = {k: v for k, v in ADDED_LOSS_FIELDS.items() if k in now}
                recorded["train"]["loss"] = {**added, **loss}
        if recorded != current:
            raise LoosefitInputError(
                cfg_path,
                "train",
                "the configuration of this command",
                "another run's",
                hint="use another --out folder, or delete this one to start over",
            )
    else:
        write_json_atomic(cfg_path, stored)
    (out / "report.json").unlink(missing_ok=True)  # a report only once the run is complete


def save_checkpoint(path: Path, data: dict) -> None:
    """Write a checkpoint atomically (a temporary file, then a rename)."""
    save_atomic(data, path)


@dataclass
class Run:
    """An open run folder and the process that trains in it.

    Attributes:
        out: the folder.
        rank, world: this process and how many train together (0, 1 without torchrun).
        log: where progress lines go (nothing on processes other than the first).
        progress: show a tqdm bar (only the first process does).
    """

    out: Path
    rank: int
    world: int
    log: typing.Callable
    progress: bool

    @property
    def main(self) -> bool:
        """The first process: the one that writes files and evaluates."""
        return self.rank == 0

    @property
    def checkpoint(self) -> Path:
        return self.out / "checkpoint.pt"

    @classmethod
    def open(cls, out: str | Path, stored: dict, seed: int, log=print, progress=True) -> Run:
        """Open (or resume) the run folder ``out`` for a run recording ``stored`` in its
        ``config.json`` (the first process does; the others wait for it), and seed torch.

        Raises:
            LoosefitInputError: ``out`` holds a run of another configuration.
        """
        out = Path(out)
        rank, world = distributed()
        if rank == 0:
            open_run(out, stored)
        else:
            log, progress = (lambda *_: None), False
        barrier()
        torch.manual_seed(seed)
        return cls(out, rank, world, log, progress)


# -- a stage ---------------------------------------------------------------------------------


class Trainer:
    """What a training stage brings to :func:`train`; each stage's module subclasses it.

    Attributes:
        config: the run's configuration.
        label: the progress bar's.
        model: the network trained (wrapped in DDP under torchrun; counted in the report).
        states: what a checkpoint holds and a resume restores, by checkpoint key: the
            networks (``"model"`` first) and their optimisers.
        sampling: the CPU generator of the stage's own random draws (checkpointed), or None.
        ddp_buffers: whether DDP broadcasts the buffers at every forward pass.
        tags: TensorBoard tags of the extra history fields :meth:`train_epoch` returns.
    """

    config: TrainerConfig
    label: str
    model: torch.nn.Module
    states: dict
    sampling: torch.Generator | None = None
    ddp_buffers: bool = True
    tags: typing.ClassVar[dict[str, str]] = {}

    def read_checkpoint(self, path: Path) -> dict:
        """The run's checkpoint, checked to be this stage's."""
        raise NotImplementedError

    def warm_start(self, path: str) -> None:
        """Load the weights of another checkpoint (``config.init``) into the networks."""
        raise NotImplementedError

    def checkpoint_fields(self) -> dict:
        """What a checkpoint holds besides the states: its ``format`` first."""
        raise NotImplementedError

    def train_epoch(self, epoch: int, net: torch.nn.Module, bar) -> tuple[dict, dict]:
        """One epoch (``epoch`` 0-based) through ``net`` (the model, or its DDP wrapper):
        the mean loss terms per step (``total`` among them), and the extra fields of the
        epoch's history record (:attr:`tags`)."""
        raise NotImplementedError

    def evaluate_now(self, epoch: int) -> bool:
        """Whether to evaluate after epoch ``epoch`` (1-based, its checkpoint written)."""
        return False

    def evaluate(self, epoch: int, record: dict, write) -> dict[str, float]:
        """Evaluate after epoch ``epoch``: TensorBoard scalars by tag (``record``: the
        epoch's history record, to note results in; ``write``: a line under the bar)."""
        return {}

    def report(self, common: dict, writer, epoch: int, history: list) -> dict:
        """The final report after ``epoch`` epochs (``history``: their records): ``common``
        (dataset, epochs, parameters, timings, machine, final loss) and the stage's own
        results."""
        raise NotImplementedError

    def format_report(self, report: dict) -> str:
        """A Markdown summary of the report."""
        raise NotImplementedError


def restore(saved: dict, states: dict, sampling: torch.Generator | None = None) -> tuple[int, list]:
    """Resume from a training checkpoint: ``states`` maps its keys to the modules and
    optimisers to load; torch's RNG (and ``sampling``'s) are put back. Returns the epoch
    reached and the loss history."""
    for key, obj in states.items():
        obj.load_state_dict(saved[key])
    torch.set_rng_state(saved["rng"].cpu())  # read onto the training device: RNGs are CPU's
    if sampling is not None:
        sampling.set_state(saved["sampling_rng"].cpu())
    return saved["epoch"], saved["history"]


# -- the loop --------------------------------------------------------------------------------


def train(stage: Trainer, run: Run, dataset: str) -> dict:
    """Train ``stage`` in ``run`` to ``stage.config.epochs`` (resuming where its checkpoint
    stopped) and report.

    Returns:
        The report (also ``report.json`` and ``report.md``); under torchrun, on processes
        other than the first, only ``{"history": ...}``.
    """
    from torch.utils.tensorboard import SummaryWriter
    from tqdm import tqdm

    config, out, log = stage.config, run.out, run.log
    epoch, history = 0, []
    if run.checkpoint.is_file():  # every process resumes from the same checkpoint
        saved = stage.read_checkpoint(run.checkpoint)
        epoch, history = restore(saved, stage.states, stage.sampling)
        log(f"resumed {run.checkpoint} at epoch {epoch}")
    elif getattr(config, "init", None):
        stage.warm_start(config.init)
        log(f"started from the weights of {config.init}")
    net = stage.model
    if run.world > 1:  # torchrun: each process a share of every batch, gradients averaged
        net = torch.nn.parallel.DistributedDataParallel(stage.model, **_ddp_buffers(stage))

    writer = SummaryWriter(str(out)) if run.main else None
    bar = tqdm(
        total=config.epochs, initial=epoch, desc=stage.label, unit="epoch", disable=not run.progress
    )
    t_start, epochs_run = time.perf_counter(), 0
    while epoch < config.epochs:
        terms, extra = stage.train_epoch(epoch, net, bar)
        if not math.isfinite(terms.get("total", 0.0)):
            raise RuntimeError(f"training diverged at epoch {epoch + 1}: loss {terms['total']}")
        epoch += 1
        epochs_run += 1
        history.append({"epoch": epoch, **extra, **terms})
        postfix = {"loss": f"{terms.get('total', float('nan')):.3g}"}
        bar.set_postfix(**postfix, **{k: f"{v:.2f}" for k, v in extra.items()})
        bar.update(1)
        if not run.main:
            continue
        for k, v in terms.items():
            writer.add_scalar(f"loss/{k}", v, epoch)
        for k, v in extra.items():
            writer.add_scalar(stage.tags[k], v, epoch)
        # the checkpoint first: a kill during an evaluation loses no training
        if epoch % config.checkpoint_every == 0 or epoch == config.epochs:
            save_checkpoint(run.checkpoint, _checkpoint(stage, epoch, history))
        if stage.evaluate_now(epoch):
            for tag, value in stage.evaluate(epoch, history[-1], bar.write).items():
                writer.add_scalar(tag, value, epoch)
    bar.close()
    seconds = time.perf_counter() - t_start
    del net  # DDP's hooks and its hold on the process group end with the loop
    barrier()
    if not run.main:  # the report is the first process's
        barrier()  # every process leaves together: none shuts down while the first writes
        return {"history": history}

    common = {
        "dataset": dataset,
        "epochs": config.epochs,
        "parameters": sum(p.numel() for p in stage.model.parameters()),
        "seconds_per_epoch": seconds / epochs_run if epochs_run else None,
        "peak_memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "machine": machine(config.device),
        "final_loss": history[-1] if history else None,
    }
    report = stage.report(common, writer, epoch, history)
    write_json_atomic(out / "report.json", report)
    (out / "report.md").write_text(stage.format_report(report))
    writer.close()
    barrier()
    return report


def _ddp_buffers(stage: Trainer) -> dict:
    """DDP's keyword for whether buffers are broadcast at every forward pass: PyTorch
    renamed ``broadcast_buffers`` to ``forward_sync_buffers`` (both keep the forward-pass
    meaning; the new one also syncs buffers once at the start, which equal buffers allow)."""
    import inspect

    params = inspect.signature(torch.nn.parallel.DistributedDataParallel).parameters
    key = "forward_sync_buffers" if "forward_sync_buffers" in params else "broadcast_buffers"
    return {key: stage.ddp_buffers}


def adam(module: torch.nn.Module, config: TrainerConfig) -> torch.optim.Adam:
    """The optimiser of every stage: Adam with the configuration's rate and weight decay."""
    return torch.optim.Adam(module.parameters(), lr=config.lr, weight_decay=config.weight_decay)


def cost_line(report: dict, parameters: str = "parameters", digits: int = 2) -> str:
    """A report's last Markdown line: parameters, seconds per epoch (``digits`` decimals),
    peak memory, machine."""
    spe = report.get("seconds_per_epoch")
    return (
        f"{report['parameters']:,} {parameters}; "
        + (f"{spe:.{digits}f} s per epoch; " if spe else "")
        + f"peak memory {report['peak_memory_mb']:.0f} MB; {report['machine']}."
    )


def _checkpoint(stage: Trainer, epoch: int, history: list) -> dict:
    """A training checkpoint: the stage's fields, its states, where the loop stands."""
    data = {**stage.checkpoint_fields()}
    data.update({key: obj.state_dict() for key, obj in stage.states.items()})
    data.update(epoch=epoch, history=history, rng=torch.get_rng_state())
    if stage.sampling is not None:
        data["sampling_rng"] = stage.sampling.get_state()
    return data
