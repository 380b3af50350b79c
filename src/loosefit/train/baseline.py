"""Training the baselines (Santesteban et al. 2019; Pan et al. 2022, virtual bones), resumable.

One stage for both (:mod:`loosefit.model.baselines`) in the training scaffold
(:mod:`loosefit.train.loop`: run folder, checkpoints, resume, logging, report):
the same data as the motion encoder (:mod:`loosefit.train.clips`: the clips on the
rollout timeline, the same frames, mirrored clips with ``mirror``), truncated
backpropagation through time in windows of ``window`` frames with the GRU's state
carried over, and the same held-out evaluation
(:func:`~loosefit.eval.rollouts.evaluate_rollouts`). Besides the scaffold's files a
run keeps ``model.pt`` (without the optimizer); a virtual-bones run also keeps its
skinning decomposition (``ssdr.npz``), computed once. ``loosefit animate`` and
``loosefit evaluate`` take a ``model.pt``/``checkpoint.pt`` of either.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import ClassVar, NamedTuple

import numpy as np
import torch

from loosefit.data.format import DatasetReader
from loosefit.eval.rollouts import evaluate_rollouts
from loosefit.geometry.skinning import root_frame_transforms
from loosefit.inference.baseline import BaselineModel, load_baseline
from loosefit.inference.checkpoints import (
    BASELINE_FORMAT,
    garment_record,
    read_checkpoint_file,
    save_atomic,
)
from loosefit.inference.model_common import arm_collision_of
from loosefit.inference.stages import Stages
from loosefit.inference.timeline import RolloutConfig
from loosefit.model.baselines import (
    BaselineConfig,
    BaselineLossConfig,
    BaselineNetwork,
    baseline_loss,
    body_joint_weights,
)
from loosefit.train.clips import (
    Clip,
    feature_statistics,
    prepare_clips,
    rollout_evaluation,
    stack_clips,
)
from loosefit.train.common import epoch_means, optimizer_step
from loosefit.train.frames import avatar_for
from loosefit.train.loop import Run, Trainer, TrainerConfig, adam, cost_line, train

CHECKPOINT_FORMAT = BASELINE_FORMAT
RAW = Stages(detail=False, lengths=False, collision=False)  # the network's own output


@dataclass
class TrainBaselineConfig(TrainerConfig):
    """One training run of a baseline (the shared fields: :class:`TrainerConfig`)."""

    epochs: int = 300  # the motion encoder's
    batch_size: int = 1  # clips side by side
    checkpoint_every: int = 5  # epochs
    model: BaselineConfig = field(default_factory=BaselineConfig)  # the method and network
    loss: BaselineLossConfig = field(default_factory=BaselineLossConfig)  # the loss weights
    rollout: RolloutConfig = field(default_factory=RolloutConfig)  # the timeline of a clip
    window: int = 50  # frames of truncated backpropagation through time
    grad_clip: float = 10.0  # max gradient norm per step
    mirror: bool = False  # also the training clips mirrored (as the motion encoder's option)
    near: float = 0.02  # santesteban: m; vertices farther from the body get diffused weights
    ssdr_iterations: int = 30  # virtual-bones: Dem Bones' global iterations
    eval_every: int = 10  # epochs; held-out rollout RMSE into TensorBoard

    # ``full``: the motion encoder's (300 epochs, batch 1, lr 1e-4); ``cpu``: 40 epochs, 16
    # clips side by side, lr 1e-3 (the motion encoder's ``cpu`` preset with the 40 epochs the
    # committed motion stage was trained for)
    PRESETS: ClassVar[dict[str, dict]] = {
        "full": {},
        "cpu": {
            "epochs": 40,
            "batch_size": 16,
            "lr": 1.0e-3,
            "checkpoint_every": 2,
            "eval_every": 10,
        },
    }


# -- the data ---------------------------------------------------------------------------------


def clip_joints(avatar, clip: Clip) -> torch.Tensor:
    """(T, J, 3, 4) the avatar's rest -> root-frame joint transforms of a clip's motion frames."""
    world = avatar.pose_motion(clip.motion).joint_transforms.float().cpu()
    P = clip.preroll
    return root_frame_transforms(world, clip.heading[P:], clip.origin[P:])


class SkinningSetup(NamedTuple):
    """What a baseline skins with (:func:`skinning_setup`)."""

    rest: torch.Tensor  # (V, 3) the rest shape
    weights: torch.Tensor  # (V, K) skinning weights over K joints or bones
    bone_mean: torch.Tensor | None  # (K, 3, 4) the mean bone transform; None: joints
    extra: list[torch.Tensor]  # per clip, per frame: joint or fitted bone transforms


def skinning_setup(
    method: str,
    reader: DatasetReader,
    avatar,
    clips: list[Clip],
    config: TrainBaselineConfig,
    cache: Path,
    *,
    log=print,
) -> SkinningSetup:
    """The rest shape, weights (and mean bone transforms) a baseline skins with.

    Santesteban: the template on the avatar's joints
    (:func:`~loosefit.geometry.skin_transfer.garment_skin_weights`). Virtual bones:
    a Dem Bones decomposition of every training frame in the root frame, cached in
    ``cache``; its rigid per-frame bone transforms are the bone network's targets.

    Returns:
        :class:`SkinningSetup`: rest (V, 3), weights (V, K), bone_mean (K, 3, 4) or None,
        and per clip the extra per-frame tensor (joint transforms, or the fitted bone
        transforms).
    """
    template = reader.template
    if method == "santesteban":
        from loosefit.geometry.skin_transfer import garment_skin_weights

        faces = avatar.collider_faces(arms=False).cpu().numpy()
        weights = garment_skin_weights(
            template.vertices,
            template.faces,
            avatar.rest_vertices.double().cpu().numpy(),
            faces,
            body_joint_weights(avatar),
            config.near,
        )
        extra = [clip_joints(avatar, c) for c in clips]
        return SkinningSetup(
            torch.from_numpy(template.vertices), torch.from_numpy(weights), None, extra
        )
    from loosefit.model.ssdr import SkinningDecomposition, SSDRConfig, decompose

    frames = torch.cat([c.target for c in clips]).numpy()
    decomp = SkinningDecomposition.load(cache) if cache.is_file() else None
    if decomp is None or len(decomp.frame_index) != len(frames):
        t0 = time.perf_counter()
        decomp = decompose(
            frames,
            template.vertices,
            SSDRConfig(
                bones=config.model.bones,
                iterations=config.ssdr_iterations,
                max_frames=None,
                seed=config.seed,
            ),
            faces=template.faces,
        )
        decomp.save(cache)
        log(
            f"skinning decomposition of {len(frames)} frames: {decomp.bones} bones, RMSE "
            f"{100 * decomp.rmse:.2f} cm in {time.perf_counter() - t0:.0f} s"
        )
    ends = np.cumsum([0] + [len(c.target) for c in clips])
    bones = torch.from_numpy(decomp.transforms)  # (N, B, 3, 4) rigid, every frame in order
    extra = [bones[a:b] for a, b in zip(ends[:-1], ends[1:], strict=True)]
    mean = bones.mean(0)
    return SkinningSetup(
        torch.from_numpy(decomp.rest), torch.from_numpy(decomp.weights), mean, extra
    )


# -- the step ---------------------------------------------------------------------------------


def run_window(
    network: BaselineNetwork, batch: dict, start: int, stop: int, hidden: torch.Tensor, loss
) -> tuple[dict | None, torch.Tensor]:
    """Timeline frames ``start:stop`` of stacked clips (:func:`stack_clips`, on the network's
    device): the loss over their motion frames (None if the window holds none) and the GRU
    state after them (detached)."""
    h, hidden = network.encode(batch["features"][:, start:stop], hidden.detach())
    t = torch.arange(start, stop, device=h.device)
    m = t[None] - batch["preroll"][:, None]  # (B, w) motion frame
    valid = (m >= 0) & (t[None] < batch["length"][:, None])
    if not valid.any():
        return None, hidden.detach()
    bi, ti = valid.nonzero(as_tuple=True)
    k = m[bi, ti]
    extra = batch["extra"][bi, k]
    santesteban = network.method == "santesteban"
    out = network.decode(h[bi, ti], extra if santesteban else None)
    terms = baseline_loss(out, batch["target"][bi, k], None if santesteban else extra, loss)
    return terms, hidden.detach()


# -- the stage --------------------------------------------------------------------------------


class BaselineTrainer(Trainer):
    """A baseline's training: its clips and skinning, its windows, its rollout evaluation."""

    def __init__(self, reader: DatasetReader, config: TrainBaselineConfig, run: Run):
        self.config, self.run, self.reader = config, run, reader
        self.template = template = reader.template
        self.label = f"train {config.model.method}"
        self.sampling = torch.Generator().manual_seed(config.seed)  # every draw of the loop
        # 1. the clips and what the method skins with
        self.floor = floor = float(reader.body["floor_height"])
        avatar = avatar_for(reader)
        t0 = time.perf_counter()
        self.clips = clips = prepare_clips(
            reader,
            "train",
            None,
            floor,
            config.rollout,
            max_frames=config.max_frames,
            mirror=config.mirror,
            joints=config.model.joints,
        )
        rest, weights, bone_mean, self.extra = skinning_setup(
            config.model.method, reader, avatar, clips, config, run.out / "ssdr.npz", log=run.log
        )
        run.log(
            f"prepared {len(clips)} train clips ({sum(c.length for c in clips)} frames) "
            f"in {time.perf_counter() - t0:.1f} s"
        )
        F, mean, std = feature_statistics(reader, clips, config.model.joints)
        # 2. the network
        self.model = BaselineNetwork(config.model, F, rest, weights, mean, std, bone_mean=bone_mean)
        self.model.to(config.device)
        self.optim = adam(self.model, config)
        self.states = {"model": self.model, "optimizer": self.optim}
        self.joint_names = tuple(clips[0].motion.joint_names)
        self.meta = {
            "model_config": {"network": asdict(config.model), "rollout": asdict(config.rollout)},
            "config": config.to_dict(),
            "garment": garment_record(template),
            "num_features": F,
            "influences": int(weights.shape[1]),
            "joint_names": list(self.joint_names),
            "floor_height": floor,
            "fps": clips[0].motion.fps,
            "body": dict(reader.body),
            "cloth": reader.manifest.get("config", {}).get("cloth"),
            "dataset": str(reader.root.resolve()),
        }

    def read_checkpoint(self, path: Path) -> dict:
        return read_checkpoint_file(path, BASELINE_FORMAT, self.config.device)

    def checkpoint_fields(self) -> dict:
        return {"format": BASELINE_FORMAT, **self.meta}

    def train_epoch(self, epoch: int, net, bar) -> tuple[dict, dict]:
        """Batches of clips in a random order, each in windows of timeline frames."""
        cfg, device, network = self.config, self.config.device, self.model
        network.train()
        order = torch.randperm(len(self.clips), generator=self.sampling).tolist()
        sums: dict[str, float] = {}
        steps = 0
        for b in range(0, len(order), cfg.batch_size):
            pick = order[b : b + cfg.batch_size]
            batch = stack_clips([self.clips[i] for i in pick], extra=[self.extra[i] for i in pick])
            batch = {k: v.to(device) for k, v in batch.items()}
            hidden = network.initial_hidden(len(pick), device)
            L = int(batch["length"].max())
            for start in range(0, L, cfg.window):
                stop = min(start + cfg.window, L)
                terms, hidden = run_window(network, batch, start, stop, hidden, cfg.loss)
                if terms is None:
                    continue
                optimizer_step(self.optim, network.parameters(), terms, cfg.grad_clip, sums)
                steps += 1
        return epoch_means(sums, steps), {}

    def current(self, path: Path) -> BaselineModel:
        """The network being trained as a model to roll out."""
        return BaselineModel(
            network=self.model,
            template=self.template,
            joint_names=self.joint_names,
            floor_height=self.floor,
            fps=self.meta["fps"],
            body=dict(self.reader.body),
            rollout_config=self.config.rollout,
            path=path,
            arm_collision=arm_collision_of(self.meta),
        )

    def evaluate_now(self, epoch: int) -> bool:
        return epoch % self.config.eval_every == 0 or epoch == self.config.epochs

    def evaluate(self, epoch: int, record: dict, write) -> dict[str, float]:
        model = self.current(self.run.checkpoint)
        return rollout_evaluation(model, self.reader, RAW, epoch, record, write)

    def report(self, common: dict, writer, epoch: int, history: list) -> dict:
        path = self.run.out / "model.pt"
        save_atomic(
            {
                "format": BASELINE_FORMAT,
                **self.meta,
                "model": self.model.state_dict(),
                "epoch": epoch,
            },
            path,
        )
        model = load_baseline(path, self.config.device)
        test = evaluate_rollouts(model, self.reader, "test", stages=RAW)
        return {"method": self.config.model.method, **common, "test": test}

    def format_report(self, report: dict) -> str:
        return format_report(report)


def train_baseline(
    data: str | Path,
    out: str | Path,
    config: TrainBaselineConfig,
    log=print,
    progress: bool = True,
) -> dict:
    """Train (or resume) a baseline on a dataset and report its held-out rollout errors.

    Args:
        data: a dataset folder.
        out: the run folder (:class:`~loosefit.train.loop.Run`): a run of this configuration
            there resumes, a run of another is refused.
        config: the run (``config.model.method`` picks the baseline).
        log, progress: where progress lines go; whether to show a tqdm bar.

    Returns:
        The report (also written to ``out/report.json`` and ``out/report.md``).
    """
    reader = DatasetReader(data)
    dataset = str(Path(data).resolve())
    run = Run.open(out, {"dataset": dataset, "train": config.to_dict()}, config.seed, log, progress)
    return train(BaselineTrainer(reader, config, run), run, dataset)


def format_report(report: dict) -> str:
    """A Markdown summary of a baseline run's report."""
    t = report["test"]
    return "\n".join(
        [
            f"# Baseline `{report['method']}`, {report['epochs']} epochs",
            "",
            "Held-out rollouts (no post-process):",
            "",
            "| frames | RMSE (cm) | Hausdorff (cm) | STED |",
            "|---:|---:|---:|---:|",
            f"| {t['frames']} | {t['rmse_cm']:.3f} | {t['hausdorff_cm']:.3f} | {t['sted']:.4f} |",
            "",
            cost_line(report),
            "",
        ]
    )
