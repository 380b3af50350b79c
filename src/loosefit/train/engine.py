"""Training the engine tier (:mod:`loosefit.model.engine`) on a simulated data set.

A run is a folder of the training scaffold (:mod:`loosefit.train.loop`: ``config.json``,
``checkpoint.pt`` written atomically, resume, TensorBoard events, ``report.json/.md``) plus
``engine.pt``: the tier alone, float32, with everything a rollout needs.

1. **The basis**: the PCA (:func:`~loosefit.model.engine.fit_basis`) of every training
   frame's garment in its root frame (the mirrored clips too, with ``mirror``).
2. **The targets**: each frame's coefficients on that basis, of the simulated garment
   (``targets="simulation"``) or of the full model's own rollout of the clip
   (``targets="rollout"``: distillation from the motion stage, decoded, before collision
   handling).
3. **The dynamics**: trained as the motion stage is (:mod:`loosefit.train.motion`): every
   clip on the rollout timeline from its settled drape, in windows of truncated
   backpropagation through time carrying the state, the previous coefficients drawn by
   scheduled sampling (the truth with a probability falling from 1 to 0 over the first
   half of the epochs, the tier's own output otherwise). The basis is orthonormal, so the
   loss is the squared vertex error within the subspace, computed on the coefficients
   alone; a flare term compares the hem's mean distance from the root's vertical axis,
   decoded on the hem's vertices only; a membrane term (off by default) the decoded
   garment's edge lengths with their rest lengths.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import ClassVar

import numpy as np
import torch

from loosefit.data.format import DatasetReader
from loosefit.errors import LoosefitInputError
from loosefit.eval.metrics import rmse
from loosefit.garment.mesh_checks import hem_loop
from loosefit.inference.checkpoints import garment_record, read_checkpoint_file, save_atomic
from loosefit.inference.engine.model import (
    ENGINE_FORMAT,
    EngineModel,
    engine_fields,
    load_engine,
    rest_coefficients,
    rollout_engine,
)
from loosefit.inference.timeline import RolloutConfig
from loosefit.model.engine import EngineConfig, EngineTier, correlate_noise, fit_basis, project
from loosefit.model.losses import ClothStructure, hem_radius, membrane_energy
from loosefit.model.motion_features import to_root_frame
from loosefit.train.clips import (
    Clip,
    feature_range,
    feature_statistics,
    pad_frames,
    prepare_clips,
)
from loosefit.train.common import epoch_means, optimizer_step
from loosefit.train.loop import Run, Trainer, TrainerConfig, adam, cost_line, train

TARGETS = ("simulation", "rollout")
# the first seed of the procedural dances a tier is trained on: far from the seeds the
# demo and the benchmarks dance (0-9), so that those stay held out
PROCEDURAL_SEED = 1000


@dataclass
class TrainEngineConfig(TrainerConfig):
    """One training run of the engine tier (the shared fields: :class:`TrainerConfig`; what
    the membrane term, the procedural dances and the samples are for:
    docs/design/notes/train_engine.md)."""

    epochs: int = 300  # passes over the training clips
    batch_size: int = 64  # clips side by side (all of the dance corpus's, mirrored)
    lr: float = 1.0e-3  # Adam's learning rate
    weight_decay: float = 0.0  # none: the tier is small and the basis bounds its output
    checkpoint_every: int = 20  # epochs
    model: EngineConfig = field(default_factory=EngineConfig)  # the tier's sizes
    rollout: RolloutConfig = field(default_factory=RolloutConfig)  # the timeline of a clip
    window: int = 50  # frames of truncated backpropagation through time
    grad_clip: float = 10.0  # max gradient norm per step
    teacher_fraction: float = 0.5  # the truth as previous state: 1 -> 0 over this share
    mirror: bool = True  # every training clip also mirrored left-right
    targets: str = "simulation"  # "simulation", or "rollout" (the full model's, distilled)
    flare: float = 1.0  # weight of the hem-flare term (cm^2, as the geometry term); 0: off
    membrane: float = 0.0  # weight of the decoded edges' mean squared strain; 0: off
    membrane_stride: int = 5  # ... taken on every this many frames (its cost is the decode's)
    length_scale: float = 100.0  # metres to centimetres in the loss
    eval_every: int = 25  # epochs; the held-out rollout RMSE into TensorBoard
    procedural: int = 0  # procedural dances added to the training clips (distilled); 0: none
    procedural_seconds: int = 12  # the length of each
    samples: int = 2  # a stochastic tier's realisations of each clip, for the energy score

    PRESETS: ClassVar[dict[str, dict]] = {"cpu": {}, "full": {}, "quick": {"epochs": 40}}

    def validate(self) -> None:
        if self.targets not in TARGETS:
            raise LoosefitInputError(
                "TrainEngineConfig", "targets", " or ".join(TARGETS), repr(self.targets)
            )
        if not (isinstance(self.window, int) and self.window >= 1):
            raise LoosefitInputError("TrainEngineConfig", "window", "an integer >= 1", self.window)
        if not (isinstance(self.procedural, int) and self.procedural >= 0):
            raise LoosefitInputError(
                "TrainEngineConfig", "procedural", "an integer >= 0", self.procedural
            )
        if self.model.noise and not (isinstance(self.samples, int) and self.samples >= 2):
            raise LoosefitInputError(
                "TrainEngineConfig", "samples", "an integer >= 2 (a stochastic tier)", self.samples
            )
        for name in ("flare", "membrane"):
            if not getattr(self, name) >= 0:
                raise LoosefitInputError(
                    "TrainEngineConfig", name, "a weight >= 0", getattr(self, name)
                )

    def teacher_probability(self, epoch: int) -> float:
        span = self.teacher_fraction * self.epochs
        return 0.0 if span <= 0 or epoch >= span else float(1.0 - epoch / span)


def rollout_targets(full_model, clips: list[Clip]) -> list[torch.Tensor]:
    """The full model's garments (motion stage, decoded; root frames) of every clip's
    motion frames (T, V, 3): the targets of a distilled tier."""
    from loosefit.inference.stages import MOTION_ONLY

    out = []
    for c in clips:
        world = torch.from_numpy(full_model.animate(c.motion, stages=MOTION_ONLY).vertices)
        P = c.preroll
        out.append(to_root_frame(world.float(), c.heading[P:], c.origin[P:]))
    return out


@torch.no_grad()
def procedural_clips(full_model, config: TrainEngineConfig, floor: float, fps: float) -> list[Clip]:
    """``config.procedural`` procedural dances on the rollout timeline, their targets the
    full model's garments (motion stage, decoded; root frames): clips as
    :func:`~loosefit.train.clips.prepare_clips` makes them."""
    from loosefit.inference.rollout import timeline
    from loosefit.model.motion_features import feature_joints, motion_features, root_frames
    from loosefit.motion.motions import load_motion

    if config.procedural == 0:
        return []
    avatar = full_model.avatar()
    clips = []
    for i in range(config.procedural):
        seed = PROCEDURAL_SEED + i
        m = load_motion(f"dance:{config.procedural_seconds}", avatar, fps=fps, seed=seed)
        rot, root, P = timeline(m, floor, config.rollout)
        H, p = (a.float() for a in root_frames(rot.double(), root.double()))
        joints = feature_joints(m.joint_names, config.model.joints)
        feats = motion_features(rot, root, m.fps, floor, joints)  # (P + T, F)
        clip = Clip(f"dance_{seed}", m, feats, H, p, None, None, P)
        (clip.target,) = rollout_targets(full_model, [clip])  # (T, V, 3)
        clips.append(clip)
    return clips


def stack_coefficients(clips: list[Clip]) -> dict[str, torch.Tensor]:
    """Clips side by side (padded by repeating their last frame): ``features`` (b, L, F),
    ``latent`` (b, T, K) the target coefficients, ``preroll`` and ``length`` (b,)."""
    L = max(c.length for c in clips)
    T = max(c.latent.shape[0] for c in clips)
    return {
        "features": torch.stack([pad_frames(c.features, L) for c in clips]),  # (b, L, F)
        "latent": torch.stack([pad_frames(c.latent, T) for c in clips]),  # (b, T, K)
        "preroll": torch.tensor([c.preroll for c in clips]),
        "length": torch.tensor([c.length for c in clips]),
    }


def energy_score_loss(
    samples: torch.Tensor, truth: torch.Tensor, vertices: int, scale: float
) -> torch.Tensor:
    """The energy score of S realisations against the truth, per clip (differentiable).

    ``mean_s d(X_s, y) - 1/(2 S^2) sum_{s, s'} d(X_s, X_s')``, d the frame's RMS vertex
    distance times ``scale`` (the coefficients of an orthonormal basis: their distance over
    sqrt(V) is the vertices').

    Args:
        samples: (S, n, K) coefficients of each clip's realisations; truth: (n, K).
        vertices: V; scale: metres to the loss's unit.

    Returns:
        (n,) the score of each clip.
    """

    def dist(a, b):
        return scale * ((a - b).pow(2).sum(-1) / vertices + 1e-12).sqrt()

    S = len(samples)
    spread = sum(dist(samples[a], samples[b]) for a in range(S) for b in range(a + 1, S))
    return dist(samples, truth).mean(0) - spread / S**2


class EngineTrainer(Trainer):
    """The engine tier's training: the basis, its clips, its windows, its evaluation."""

    label = "train engine tier"
    tags: ClassVar[dict[str, str]] = {"teacher": "train/teacher_probability"}

    def __init__(
        self,
        reader: DatasetReader,
        full_model,
        config: TrainEngineConfig,
        run: Run,
    ):
        self.config, self.run, self.reader = config, run, reader
        self.full_model = full_model
        self.template = reader.template
        self.sampling = torch.Generator().manual_seed(config.seed)
        self.floor = float(reader.body["floor_height"])
        t0 = time.perf_counter()
        # 1. the clips on the rollout timeline, and the targets
        self.clips = clips = prepare_clips(
            reader,
            "train",
            None,
            self.floor,
            config.rollout,
            max_frames=config.max_frames,
            mirror=config.mirror,
            joints=config.model.joints,
        )
        if config.targets == "rollout":
            for c, x in zip(clips, rollout_targets(full_model, clips), strict=True):
                c.target = x
        self.fps = clips[0].motion.fps
        clips += procedural_clips(full_model, config, self.floor, self.fps)
        frames = torch.cat([c.target for c in clips])  # (N, V, 3)
        run.log(
            f"prepared {len(clips)} train clips ({len(frames)} frames) "
            f"in {time.perf_counter() - t0:.1f} s"
        )
        # 2. the basis, the tier
        basis = fit_basis(frames, config.model.basis)
        run.log(
            f"basis of {config.model.basis}: {100 * float(basis.explained.sum()):.3f} % of "
            "the variance"
        )
        F, mean, std = feature_statistics(reader, clips, config.model.joints)
        rest = full_model.rest_state.float().cpu()
        low, high = feature_range(clips)
        self.model = EngineTier(
            F, config.model, basis, mean, std, feature_low=low, feature_high=high
        )
        self.model.rest.copy_(rest_coefficients(self.model, rest))
        for c in clips:
            c.latent = project(c.target, basis.mean, basis.basis)  # (T, K) the targets
        hem = torch.from_numpy(hem_loop(self.template.vertices, self.template.faces))
        self.hem_mean = basis.mean[hem]  # (H, 3)
        self.hem_basis = basis.basis[:, hem]  # (K, H, 3)
        structure = ClothStructure.from_template(self.template)
        self.edges = (structure.edges, structure.rest_lengths)
        self.optim = adam(self.model, config)
        self.states = {"model": self.model, "optimizer": self.optim}
        self.joint_names = tuple(clips[0].motion.joint_names)
        self.meta = {
            **engine_fields(self.model),
            "config": config.to_dict(),
            "garment": garment_record(self.template),
            "joint_names": list(self.joint_names),
            "floor_height": self.floor,
            "fps": self.fps,
            "body": dict(reader.body),
            "record": {
                "dataset": str(Path(reader.root).resolve()),
                "targets": config.targets,
                "motion_checkpoint": str(Path(full_model.path).resolve()),
                "explained_variance": float(basis.explained.sum()),
            },
        }
        self.meta["model_config"]["rollout"] = asdict(config.rollout)

    def read_checkpoint(self, path: Path) -> dict:
        return read_checkpoint_file(path, ENGINE_FORMAT)

    def checkpoint_fields(self) -> dict:
        return {"format": ENGINE_FORMAT, **self.meta}

    def flare(self, c: torch.Tensor) -> torch.Tensor:
        """(b, K) coefficients to (b,) the hem's flare (m)."""
        hem = self.hem_mean + torch.einsum("bk,khd->bhd", c, self.hem_basis)
        return hem_radius(hem, torch.arange(hem.shape[1]))

    def run_window(self, batch, start: int, stop: int, hidden, previous, teacher: float):
        """Frames ``start:stop`` of stacked clips: the loss terms (means over the valid
        (clip, frame) pairs) and the state to carry on (detached)."""
        cfg = self.config
        s2 = cfg.length_scale**2
        P, L = batch["preroll"], batch["length"]
        sums = {"geometry": 0.0, "flare": 0.0, "membrane": 0.0, "energy": 0.0}
        count = 0
        N = self.model.config.noise
        S = cfg.samples if N else 1  # a stochastic tier's realisations, side by side
        V = self.template.num_vertices
        rho = float(self.model.config.noise_correlation)
        for t in range(start, stop):
            z = None
            if N:  # carried across windows (and frames, where the tier's noise is correlated)
                white = torch.randn(1, len(previous), N, generator=self.sampling)
                z = correlate_noise(white, rho, None if t == 0 else self.noise_state)[0]
                self.noise_state = z
            c, hidden = self.model(batch["features"][:, t], previous, hidden, z)
            valid = (t >= P) & (t < L)  # (b,)
            previous = c.detach()
            if not valid.any():
                continue
            i = (t - P).clamp(0, batch["latent"].shape[1] - 1)
            truth = batch["latent"][torch.arange(len(P)), i]  # (b, K)
            w = valid.float()
            if N:
                n = len(P) // S
                es = energy_score_loss(c.view(S, n, -1), truth[:n], V, cfg.length_scale)  # (n,)
                sums["energy"] = sums["energy"] + (w[:n] * es).sum() * S
            else:
                sq = (w * (c - truth).pow(2).sum(-1)).sum()
                sums["geometry"] = sums["geometry"] + s2 * sq / V
                if cfg.flare > 0:
                    d = self.flare(c) - self.flare(truth)
                    sums["flare"] = sums["flare"] + cfg.flare * s2 * (w * d.pow(2)).sum()
            if cfg.membrane > 0 and t % cfg.membrane_stride == 0:
                e = membrane_energy(self.model.decode(c), *self.edges)  # (b,)
                scale = cfg.membrane * cfg.membrane_stride  # the frames it stands for
                sums["membrane"] = sums["membrane"] + scale * (w * e).sum()
            count += int(valid.sum())
            if teacher > 0:
                use = (torch.rand(len(P), generator=self.sampling) < teacher) & valid
                previous = torch.where(use[:, None], truth, previous)
        terms = {k: v / max(count, 1) for k, v in sums.items() if torch.is_tensor(v)}
        if terms:
            terms["total"] = sum(terms.values())
        return terms, hidden.detach(), previous

    def train_epoch(self, epoch: int, net, bar) -> tuple[dict, dict]:
        cfg = self.config
        self.model.train()
        teacher = cfg.teacher_probability(epoch)
        order = torch.randperm(len(self.clips), generator=self.sampling).tolist()
        sums: dict[str, float] = {}
        steps = 0
        for b in range(0, len(order), cfg.batch_size):
            clips = [self.clips[i] for i in order[b : b + cfg.batch_size]]
            batch = stack_coefficients(clips)
            if self.model.config.noise:  # each clip's realisations, the samples in blocks
                batch = {k: v.repeat(cfg.samples, *[1] * (v.ndim - 1)) for k, v in batch.items()}
            n = len(batch["preroll"])
            hidden = self.model.initial_hidden(n)
            previous = self.model.initial_coefficients(n)
            L = max(c.length for c in clips)
            for start in range(0, L, cfg.window):
                terms, hidden, previous = self.run_window(
                    batch, start, min(start + cfg.window, L), hidden, previous, teacher
                )
                if "total" not in terms:
                    continue  # a window of preroll frames only
                optimizer_step(self.optim, self.model.parameters(), terms, cfg.grad_clip, sums)
                steps += 1
        return epoch_means(sums, steps), {"teacher": teacher}

    def current(self) -> EngineModel:
        return EngineModel(
            tier=self.model,
            template=self.template,
            joint_names=self.joint_names,
            floor_height=self.floor,
            fps=self.fps,
            body=dict(self.reader.body),
            rollout_config=self.config.rollout,
            path=self.run.checkpoint,
            record=self.meta["record"],
        )

    def evaluate_now(self, epoch: int) -> bool:
        return epoch % self.config.eval_every == 0 or epoch == self.config.epochs

    def evaluate(self, epoch: int, record: dict, write) -> dict[str, float]:
        self.model.eval()
        err = held_out_errors(self.current(), self.reader)
        record["test_rollout_rmse_cm"] = err["rmse_cm"]
        write(f"epoch {epoch}: held-out rollout RMSE {err['rmse_cm']:.2f} cm")
        return {"test/rollout_rmse_cm": err["rmse_cm"]}

    def report(self, common: dict, writer, epoch: int, history: list) -> dict:
        path = self.run.out / "engine.pt"
        weights = {k: v.detach().cpu() for k, v in self.model.state_dict().items()}
        save_atomic({"format": ENGINE_FORMAT, **self.meta, "model": weights, "epoch": epoch}, path)
        model = load_engine(path)
        return {
            **common,
            "targets": self.config.targets,
            "basis": self.config.model.basis,
            "test": held_out_errors(model, self.reader),
        }

    def format_report(self, report: dict) -> str:
        t = report["test"]
        lines = [
            f"# Engine tier (basis {report['basis']}, targets: {report['targets']}), "
            f"{report['epochs']} epochs",
            "",
            "Rollouts of the held-out clips from their first frame, against the simulation.",
            "",
            "| clip | frames | RMSE cm |",
            "|---|---:|---:|",
        ]
        for name, c in t["clips"].items():
            lines.append(f"| {name} | {c['frames']} | {c['rmse_cm']:.3f} |")
        lines += ["", f"All frames: {t['rmse_cm']:.3f} cm.", "", cost_line(report), ""]
        return "\n".join(lines)


def held_out_errors(model: EngineModel, reader: DatasetReader) -> dict:
    """The tier's rollout of every held-out clip against the simulation: RMSE (cm) per
    clip and over all their frames."""
    clips, sq, n = {}, 0.0, 0
    for name in reader.training_clips("test"):
        seq = reader.read(name)
        x = rollout_engine(model, seq.motion)
        truth = np.asarray(seq.garment_vertices, np.float32)
        e = 100 * rmse(x, truth)
        clips[name] = {"frames": len(x), "rmse_cm": e}
        sq, n = sq + e**2 * len(x), n + len(x)
    return {"clips": clips, "rmse_cm": float(np.sqrt(sq / max(n, 1)))}


def train_engine(
    data: str | Path,
    motion: str | Path,
    out: str | Path,
    config: TrainEngineConfig,
    log=print,
    progress: bool = True,
) -> dict:
    """Train (or resume) the engine tier of a full model on its data set and report.

    Args:
        data: a data set folder (its ``train`` clips are learned, its ``test`` clips held
            out).
        motion: the full model's motion-stage checkpoint (the settled drape the tier starts
            from, and the teacher of ``targets="rollout"``).
        out: the run folder.
        config: the run.

    Returns:
        The report (also ``out/report.json`` and ``out/report.md``).
    """
    from loosefit.garment.fingerprint import same_garment
    from loosefit.inference.loader import load_model

    reader = DatasetReader(data)
    torch.set_default_device("cpu")
    full = load_model(motion)
    if not same_garment(full.template, reader.template):
        raise LoosefitInputError(
            motion,
            "garment",
            f"the garment of {reader.root}",
            "another garment",
            hint="the motion checkpoint of a model trained on this data set",
        )
    dataset = str(Path(data).resolve())
    stored = {"dataset": dataset, "motion": str(Path(motion).resolve()), "train": config.to_dict()}
    run = Run.open(out, stored, config.seed, log, progress)
    stage = EngineTrainer(reader, full, config, run)
    return train(stage, run, dataset)


def record_feature_range(path: str | Path, data: str | Path) -> tuple[torch.Tensor, torch.Tensor]:
    """Write into an engine-tier checkpoint the range of its features over its data set's
    training frames (what :class:`EngineTrainer` records in a new run; the weights are left
    as they are), atomically.

    Returns:
        The least and greatest value (F,) of each feature.

    Raises:
        LoosefitInputError: not an engine-tier checkpoint, or a data set of other features.
    """
    path = Path(path)
    data_dict = read_checkpoint_file(path, ENGINE_FORMAT)
    cfg = TrainEngineConfig.from_dict(data_dict["config"])  # the run's clips, as trained
    clips = prepare_clips(
        DatasetReader(data),
        "train",
        None,
        float(data_dict["floor_height"]),
        cfg.rollout,
        max_frames=cfg.max_frames,
        mirror=cfg.mirror,
        joints=cfg.model.joints,
    )
    low, high = feature_range(clips)
    F = int(data_dict["num_features"])
    if low.shape != (F,):
        raise LoosefitInputError(data, "features", F, tuple(low.shape))
    data_dict["model"]["feature_low"], data_dict["model"]["feature_high"] = low, high
    save_atomic(data_dict, path)
    return low, high
