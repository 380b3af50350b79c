"""Training the dynamic motion encoder (paper 3.3, Eqs. 10-12) on a frozen generative model.

A run is a folder like the generative model's (``config.json``,
``checkpoint.pt`` written atomically, TensorBoard events, ``report.json/.md``)
plus ``model.pt``: the trained encoder alone, half precision, for sharing.

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
import resource
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
import torch

from loosefit.body.mirror import mirror_garment, mirror_motion, vertex_twins
from loosefit.data.format import DatasetReader, write_json_atomic
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
from loosefit.model.generative import GarmentGenerativeModel
from loosefit.model.motion_encoder import DynamicMotionEncoder, MotionEncoderConfig
from loosefit.model.motion_features import (
    feature_joints,
    motion_features,
    num_features,
    root_frames,
    to_root_frame,
)
from loosefit.model.physics import (
    ClothStructure,
    PhysicsLossConfig,
    active_terms,
    hem_radius,
    physics_terms,
)
from loosefit.model.rollout import (
    MOTION_ONLY,
    RolloutConfig,
    change_frame,
    latent_codes,
    timeline,
)
from loosefit.train.common import (
    apply_overrides,
    autocast,
    barrier,
    check_device_precision,
    check_precision,
    distributed,
    epoch_means,
    machine,
    open_run,
    optimizer_step,
    restore_training,
    shard,
)
from loosefit.train.frames import avatar_for
from loosefit.types import Motion

CHECKPOINT_FORMAT = MOTION_FORMAT


@dataclass
class MotionLossConfig:
    """Eqs. 10-12 and the length unit of the geometry terms."""

    laplacian: float = 1.5  # lambda_4
    latent: float = 0.5  # lambda_5
    length_scale: float = 100.0  # metres to centimetres, as in the generative loss
    # physics terms (loosefit.model.physics), 0: off. The collision term needs
    # the body at every frame and is taken by the generative stage only
    membrane: float = 0.0  # edge lengths against rest
    bending: float = 0.0  # dihedral angles against rest
    collision: float = 0.0
    collision_epsilon: float = 0.002
    # the hem's flare (its mean distance from the root's vertical axis) against the
    # simulation's, squared, in the length unit (a network that averages fold
    # configurations pulls the hem in); 0: off
    flare: float = 0.0

    def __post_init__(self) -> None:
        if not (isinstance(self.flare, (int, float)) and self.flare >= 0):
            raise LoosefitInputError("MotionLossConfig", "flare", "a weight >= 0", self.flare)
        if self.collision:
            raise LoosefitInputError(
                "MotionLossConfig",
                "collision",
                "0 (the motion stage takes membrane and bending)",
                self.collision,
            )
        PhysicsLossConfig(self.membrane, self.bending, self.collision, self.collision_epsilon)


@dataclass
class TrainMotionConfig:
    """One training run of the dynamic motion encoder."""

    model: MotionEncoderConfig = field(default_factory=MotionEncoderConfig)
    loss: MotionLossConfig = field(default_factory=MotionLossConfig)
    rollout: RolloutConfig = field(default_factory=RolloutConfig)
    epochs: int = 300
    batch_size: int = 1  # clips run side by side
    window: int = 50  # frames of truncated backpropagation through time
    lr: float = 1.0e-4
    weight_decay: float = 1.0e-3
    grad_clip: float = 10.0  # max gradient norm per step
    previous: str = "scheduled"  # "scheduled" (sampling, see the module) or "teacher"
    teacher_start: float = 1.0  # probability of a ground-truth previous state at epoch 0
    teacher_fraction: float = 0.5  # ... falling to teacher_end over this fraction of the epochs
    teacher_end: float = 0.0  # ... and staying there for the rest of training
    # differentiate the loss through the encoder's own previous predictions within a window
    # (unrolled training), so it learns to correct what it fed itself, not only to use it
    unroll: bool = False
    # also train on every training clip mirrored left-right (the motion danced the other way
    # round, the simulated garment reflected onto its twin vertices): twice the data for a
    # mirror-symmetric garment, no simulation needed
    mirror: bool = False
    # m, std of Gaussian noise on every vertex of a ground-truth previous state (0: none):
    # teaches the encoder to use a previous state that is close to, but not, the truth
    previous_noise: float = 0.0
    checkpoint_every: int = 5  # epochs
    eval_every: int = 10  # epochs; held-out rollout errors into TensorBoard
    max_frames: int | None = None  # per clip, for quick runs
    seed: int = 0
    device: str = "cpu"
    precision: str = "fp32"  # the forward passes': "fp32", or "bf16" (autocast; see the module)
    # warm start: a motion checkpoint (a run's model.pt or checkpoint.pt, or a packaged
    # motion.pt) of the same encoder configuration and features whose weights the run
    # starts from (a fresh optimiser); its generative model may be another (fine-tuning)
    init: str | None = None

    def __post_init__(self) -> None:
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

    @classmethod
    def preset(cls, name: str, **overrides) -> TrainMotionConfig:
        """``full``: the paper's (300 epochs, batch 1, lr 1e-4); ``cpu``: fewer, batched epochs.

        ``cpu`` runs up to 16 clips side by side (all of salsa's 10 training clips:
        on a CPU a step of 10 costs about what a step of 3 does) with a 10x learning
        rate (1e-3) for 60 epochs; the encoder, the loss and the windows are the paper's.
        """
        prev = overrides.pop("previous_state", None)
        joints = overrides.pop("joints", None)
        if name == "full":
            cfg = cls()
        elif name == "cpu":
            cfg = cls(epochs=60, batch_size=16, lr=1.0e-3, checkpoint_every=2, eval_every=10)
        else:
            raise LoosefitInputError("--preset", "preset", "full or cpu", repr(name))
        if prev is not None:
            cfg.model.previous_state = bool(prev)
        if joints is not None:
            cfg.model = replace(cfg.model, joints=joints)  # validated
        apply_overrides(cfg, overrides).__post_init__()
        return cfg

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> TrainMotionConfig:
        d = dict(d)
        d["model"] = MotionEncoderConfig(**d["model"])
        d["loss"] = MotionLossConfig(**d["loss"])
        d["rollout"] = RolloutConfig(**d["rollout"])
        return cls(**d)

    def teacher_probability(self, epoch: int) -> float:
        """The chance of a ground-truth previous state during epoch ``epoch`` (0-based)."""
        if self.previous == "teacher":
            return 1.0
        span = self.teacher_fraction * self.epochs
        if span <= 0 or epoch >= span:
            return float(self.teacher_end)
        a, b = self.teacher_start, self.teacher_end
        return float(a + (b - a) * epoch / span)


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


# -- the data ------------------------------------------------------------------------


@dataclass
class Clip:
    """One clip on the rollout timeline (P frames before the motion, then T).

    Attributes:
        name: the clip.
        motion: the body motion (T frames).
        features: (P + T, F) motion features.
        heading: (P + T, 3, 3) and ``origin`` (P + T, 3): the root frames.
        target: (T, V, 3) simulated garment, root frame.
        latent: (T, latent) the generative encoder's code of ``target`` (Z*), or None
            when prepared without a generative model (the baselines').
        preroll: P.
    """

    name: str
    motion: Motion
    features: torch.Tensor
    heading: torch.Tensor
    origin: torch.Tensor
    target: torch.Tensor
    latent: torch.Tensor | None
    preroll: int

    @property
    def length(self) -> int:
        return int(self.features.shape[0])


@torch.no_grad()
def prepare_clips(
    reader: DatasetReader,
    split: str,
    generative: GarmentGenerativeModel | None,
    floor_height: float,
    config: RolloutConfig,
    max_frames: int | None = None,
    mirror: bool = False,
    joints: str = "all",
) -> list[Clip]:
    """Every clip of a split on the rollout timeline, with its targets (and, given a
    generative model, their latent codes).

    ``mirror`` adds each clip mirrored left-right (``NAME~mirror``): the motion by
    :func:`~loosefit.body.mirror.mirror_motion`, the simulated garment reflected
    about X = 0 onto its twin vertices (:func:`~loosefit.body.mirror.vertex_twins`;
    the garment must be mirror-symmetric). Physics has no handedness, so that is
    the simulation of the mirrored motion, up to the body's own asymmetry (mm).
    ``joints`` names the joint set of the features (``MotionEncoderConfig.joints``).
    """
    names = reader.training_clips(split)
    twins = vertex_twins(reader.template.vertices) if mirror else None
    clips = []
    for name in names:
        seq = reader.read(name)
        motion = seq.motion if max_frames is None else seq.motion.slice(0, max_frames)
        garment = seq.garment_vertices[: motion.num_frames]
        versions = [(name, motion, garment)]
        if mirror:
            versions.append(
                (f"{name}~mirror", mirror_motion(motion), mirror_garment(garment, twins))
            )
        for label, m, v in versions:
            rot, root, P = timeline(m, floor_height, config)
            H, p = (a.float() for a in root_frames(rot.double(), root.double()))
            target = to_root_frame(
                torch.from_numpy(np.ascontiguousarray(v, np.float32)), H[P:], p[P:]
            )
            feats = motion_features(
                rot, root, m.fps, floor_height, feature_joints(m.joint_names, joints)
            )
            clips.append(
                Clip(
                    label,
                    m,
                    feats,
                    H,
                    p,
                    target,
                    None if generative is None else latent_codes(generative, target),
                    P,
                )
            )
    return clips


def rest_state_for(reader: DatasetReader, fps: float) -> torch.Tensor:
    """(V, 3) the settled drape of the dataset's garment (its cloth configuration)."""
    from loosefit.sim.cloth_config import ClothConfig
    from loosefit.sim.driver import settle

    cloth = reader.manifest.get("config", {}).get("cloth")
    if cloth is None:
        raise LoosefitInputError(
            reader.root / "manifest.json",
            "config.cloth",
            "the cloth configuration of the "
            "simulation (to settle the garment where rollouts start)",
            "none",
        )
    cloth = dict(cloth)
    cloth["device"] = "cpu"
    return torch.from_numpy(settle(avatar_for(reader), reader.template, ClothConfig(**cloth), fps))


# -- checkpoints -----------------------------------------------------------------------


def save_checkpoint(
    path: Path, encoder: DynamicMotionEncoder, meta: dict, half: bool = False, **state
) -> None:
    """Write a checkpoint atomically; ``half`` stores floating weights in half precision."""
    weights = half_weights(encoder.state_dict()) if half else encoder.state_dict()
    save_atomic({"format": MOTION_FORMAT, **meta, "model": weights, **state}, path)


def training_config(path: str | Path) -> TrainMotionConfig | None:
    """The training configuration a motion-stage checkpoint records (None: a packaged one)."""
    data = read_checkpoint_file(path, MOTION_FORMAT)
    return TrainMotionConfig.from_dict(data["config"]) if "config" in data else None


# -- training --------------------------------------------------------------------------


def pad_frames(x: torch.Tensor, n: int) -> torch.Tensor:
    """Frames (T, ...) padded to ``n`` by repeating the last (clips stacked side by side)."""
    return torch.cat([x, x[-1:].expand(n - len(x), *x.shape[1:])]) if len(x) < n else x


def _stack(clips: list[Clip], longest: list[Clip] | None = None) -> dict[str, torch.Tensor]:
    """Clips side by side, padded by repeating their last frame to the longest of
    ``longest`` (the whole batch, when ``clips`` is one process's part of it; default
    ``clips``)."""
    longest = clips if longest is None else longest
    L = max(c.length for c in longest)
    T = max(c.target.shape[0] for c in longest)

    return {
        "features": torch.stack([pad_frames(c.features, L) for c in clips]),  # (B, L, F)
        "heading": torch.stack([pad_frames(c.heading, L) for c in clips]),
        "origin": torch.stack([pad_frames(c.origin, L) for c in clips]),
        "target": torch.stack([pad_frames(c.target, T) for c in clips]),  # (B, T, V, 3)
        "latent": torch.stack([pad_frames(c.latent, T) for c in clips]),
        "preroll": torch.tensor([c.preroll for c in clips]),
        "length": torch.tensor([c.length for c in clips]),
    }


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


def share_batch(
    clips: list[Clip], rank: int, world: int, device: torch.device
) -> tuple[dict[str, torch.Tensor], BatchPart]:
    """This process's clips of a batch, stacked (padded to the whole batch's frames) on
    ``device``, and where they sit in the batch."""
    mine, share = shard(len(clips), rank, world)
    batch = _stack([clips[i] for i in mine.tolist()], clips)
    preroll, length = (torch.tensor([getattr(c, a) for c in clips]) for a in ("preroll", "length"))
    part = BatchPart(mine, preroll, length, 1.0 if share > 0 else 0.0)
    return {k: v.to(device) for k, v in batch.items()}, part


def run_window(
    encoder: DynamicMotionEncoder,
    generative: GarmentGenerativeModel,
    laplacian,
    batch: dict[str, torch.Tensor],
    start: int,
    stop: int,
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
) -> tuple[dict[str, torch.Tensor], torch.Tensor, torch.Tensor]:
    """Frames ``start:stop`` of stacked clips: the loss and the state to carry on.

    Args:
        encoder, generative, laplacian: the networks (the generative one frozen; the
            encoder may be wrapped in DDP).
        batch: :func:`_stack` of b clips, on the networks' device.
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
        The loss terms (this process's share of the means over the whole batch's
        valid (clip, frame) pairs of the window: they sum to them over the processes;
        ``total`` differentiable w.r.t. the encoder through this window only, and
        without a gradient when the window holds no valid pair), the detached GRU
        state and the previous garment for the next window.
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
    for t in range(start, stop):
        if t > 0:
            previous = change_frame(previous, H[:, t - 1], p[:, t - 1], H[:, t], p[:, t])
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
            if loss.membrane > 0 or loss.bending > 0:
                for key, e in physics_terms(v, structure, loss).items():  # (b,) each
                    sums[key] = sums.get(key, 0.0) + (w * e).sum()
            if loss.flare > 0:
                if hem is None:
                    raise ValueError("the flare term needs the garment's hem vertices")
                d = s * (hem_radius(v, hem) - hem_radius(vt, hem))  # (b,)
                sums["flare"] = sums.get("flare", 0.0) + loss.flare * (w * d.pow(2)).sum()
        previous = v if unroll else v.detach()
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
    return terms, hidden.detach(), previous.detach()


def train_motion(
    data: str | Path,
    generative: str | Path,
    out: str | Path,
    config: TrainMotionConfig,
    log=print,
    progress: bool = True,
    rest_state: torch.Tensor | None = None,
) -> dict:
    """Train (or resume) the dynamic motion encoder on a dataset and report rollout errors.

    Args:
        data: a dataset folder.
        generative: the trained generative model's checkpoint (frozen here).
        out: the run folder; an existing run with the same configuration resumes.
        config: the run.
        log: where progress lines go.
        progress: show a tqdm bar.
        rest_state: (V, 3) the garment's settled drape in the rest pose's root frame;
            by default simulated with the dataset's cloth configuration
            (:func:`rest_state_for`, cached in the run folder).

    Returns:
        The report (also ``out/report.json`` and ``out/report.md``).
    """
    from torch.utils.tensorboard import SummaryWriter
    from tqdm import tqdm

    out = Path(out)
    reader = DatasetReader(data)
    template = reader.template
    device = torch.device(config.device)
    check_device_precision(config.precision, device)
    gpath = Path(generative).resolve()
    gmodel, _ = load_generative(gpath, template, device)
    for prm in gmodel.parameters():
        prm.requires_grad_(False)
    gmeta = {
        "relative": os.path.relpath(gpath, out.resolve()),
        "absolute": str(gpath),
        "fingerprint": model_fingerprint(gmodel),
    }
    ckpt_path = out / "checkpoint.pt"
    rank, world = distributed()
    main = rank == 0
    if main:
        open_run(
            out,
            {
                "dataset": str(Path(data).resolve()),
                "generative": gmeta["fingerprint"],
                "train": config.to_dict(),
            },
        )
    else:
        log, progress = (lambda *_: None), False
    barrier()

    torch.manual_seed(config.seed)
    gen = torch.Generator().manual_seed(config.seed)  # every random draw of the loop
    floor = float(reader.body["floor_height"])
    t0 = time.perf_counter()
    train = prepare_clips(
        reader,
        "train",
        gmodel,
        floor,
        config.rollout,
        config.max_frames,
        config.mirror,
        config.model.joints,
    )
    fps = train[0].motion.fps
    rest_path = out / "rest_state.npy"
    if rest_state is None and main and not rest_path.is_file():
        np.save(rest_path, rest_state_for(reader, fps).numpy())  # settled once, by the first
    barrier()
    if rest_state is not None:
        rest = torch.as_tensor(rest_state).float()
    else:
        rest = torch.from_numpy(np.load(rest_path, allow_pickle=False))
    log(
        f"prepared {len(train)} train clips ({sum(c.length for c in train)} frames) "
        f"in {time.perf_counter() - t0:.1f} s"
    )
    all_feats = torch.cat([c.features for c in train])
    F = all_feats.shape[1]
    joint_names = train[0].motion.joint_names
    expected = num_features(len(feature_joints(joint_names, config.model.joints)) + 1)
    if F != expected:
        raise LoosefitInputError(reader.root, "features", expected, F)
    encoder = DynamicMotionEncoder(gmodel, F, config.model, all_feats.mean(0), all_feats.std(0))
    encoder.to(device)
    lap = Laplacian(template.faces, template.num_vertices).to(device)
    structure = ClothStructure.from_template(template).to(device)
    hem = torch.from_numpy(hem_loop(template.vertices, template.faces)).to(device)
    optim = torch.optim.Adam(encoder.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    meta = {
        "model_config": {"encoder": asdict(config.model), "rollout": asdict(config.rollout)},
        "config": config.to_dict(),
        "generative": gmeta,
        "garment": garment_record(template),
        "num_features": F,
        "joint_names": list(joint_names),
        "floor_height": floor,
        "fps": fps,
        "body": dict(reader.body),
        "rest_state": rest.numpy(),
        "cloth": reader.manifest.get("config", {}).get("cloth"),  # the physics of the data
        "physics_terms": list(active_terms(config.loss)),
        "dataset": str(Path(data).resolve()),
    }
    epoch, history = 0, []
    if ckpt_path.is_file():  # every process resumes from the same checkpoint
        saved = read_checkpoint_file(ckpt_path, MOTION_FORMAT, device)
        epoch, history = restore_training(saved, {"model": encoder, "optimizer": optim}, gen)
        log(f"resumed {ckpt_path} at epoch {epoch}")
    elif config.init:
        warm_start(encoder, config.init, config.model, F, device)
        log(f"started from the weights of {config.init}")
    net = encoder
    if world > 1:  # torchrun: each process a share of every batch's clips, gradients averaged
        # (the encoder runs once per frame before a window's backward: DDP's hooks fire once
        # per weight; its buffers are fixed, no need to broadcast them at every frame)
        net = torch.nn.parallel.DistributedDataParallel(encoder, broadcast_buffers=False)
    rest_device = rest.to(device)

    writer = SummaryWriter(str(out)) if main else None
    bar = tqdm(
        total=config.epochs,
        initial=epoch,
        desc="train motion encoder",
        unit="epoch",
        disable=not progress,
    )
    t_start, epochs_run = time.perf_counter(), 0
    while epoch < config.epochs:
        encoder.train()
        teacher = config.teacher_probability(epoch)
        order = torch.randperm(len(train), generator=gen).tolist()
        sums: dict[str, float] = {}
        steps = 0
        for b in range(0, len(order), config.batch_size):
            clips = [train[i] for i in order[b : b + config.batch_size]]
            batch, part = share_batch(clips, rank, world, device)  # this process's clips
            n = len(part.rows)
            hidden = encoder.initial_hidden(n, device)
            previous = rest_device[None].expand(n, -1, -1).clone()  # (n, V, 3)
            L = max(c.length for c in clips)
            for start in range(0, L, config.window):
                terms, hidden, previous = run_window(
                    net,
                    gmodel,
                    lap,
                    batch,
                    start,
                    min(start + config.window, L),
                    hidden,
                    previous,
                    teacher,
                    config.loss,
                    gen,
                    config.previous_noise,
                    config.unroll,
                    part,
                    config.precision,
                    structure,
                    hem,
                )
                if not terms["total"].requires_grad:
                    continue  # a window with no motion frame in the batch (all preroll)
                optimizer_step(optim, encoder.parameters(), terms, config.grad_clip, sums, world)
                steps += 1
        sums = epoch_means(sums, steps, epoch)
        epoch += 1
        epochs_run += 1
        history.append({"epoch": epoch, "teacher": teacher, **sums})
        bar.set_postfix(loss=f"{sums.get('total', float('nan')):.3g}", teacher=f"{teacher:.2f}")
        bar.update(1)
        if not main:
            continue
        for k, v in sums.items():
            writer.add_scalar(f"loss/{k}", v, epoch)
        writer.add_scalar("train/teacher_probability", teacher, epoch)
        if epoch % config.checkpoint_every == 0 or epoch == config.epochs:
            save_checkpoint(
                ckpt_path,
                encoder,
                meta,
                optimizer=optim.state_dict(),
                epoch=epoch,
                history=history,
                rng=torch.get_rng_state(),
                sampling_rng=gen.get_state(),
            )
        if epoch % config.eval_every == 0 or epoch == config.epochs:
            current = AnimationModel(
                gmodel,
                encoder,
                template,
                rest_device,
                tuple(joint_names),
                floor,
                fps,
                dict(reader.body),
                config.rollout,
                ckpt_path,
            )
            err = evaluate_rollouts(current, reader, "test", surface=False, stages=MOTION_ONLY)
            writer.add_scalar("test/rollout_rmse_cm", err["rmse_cm"], epoch)
            history[-1]["test_rollout_rmse_cm"] = err["rmse_cm"]
            bar.write(f"epoch {epoch}: held-out rollout RMSE {err['rmse_cm']:.2f} cm")
    bar.close()
    seconds = time.perf_counter() - t_start
    barrier()
    if not main:  # the model, the report and its evaluation are the first process's
        return {"history": history}
    save_checkpoint(out / "model.pt", encoder, meta, half=True, epoch=epoch)

    model = load_animation_model(out / "model.pt", gpath, device)
    report = {
        "previous_state": config.model.previous_state,
        "previous": config.previous,
        "dataset": str(Path(data).resolve()),
        "generative": str(gpath),
        "epochs": config.epochs,
        "parameters": sum(p.numel() for p in encoder.parameters()),
        "seconds_per_epoch": seconds / epochs_run if epochs_run else None,
        "peak_memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "machine": machine(config.device),
        "final_loss": history[-1] if history else None,
        "test": evaluate_rollouts(model, reader, "test", stages=MOTION_ONLY),
    }
    write_json_atomic(out / "report.json", report)
    (out / "report.md").write_text(format_report(report))
    writer.close()
    return report


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
    spe = report.get("seconds_per_epoch")
    lines += [
        "",
        f"{report['parameters']:,} parameters; "
        + (f"{spe:.1f} s per epoch; " if spe else "")
        + f"peak memory {report['peak_memory_mb']:.0f} MB; {report['machine']}.",
        "",
    ]
    return "\n".join(lines)
