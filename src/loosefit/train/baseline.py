"""Training the baselines (Santesteban et al. 2019; Pan et al. 2022, virtual bones), resumable.

One training loop for both (:mod:`loosefit.model.baselines`): the same data as
the motion encoder (the clips on the rollout timeline, the same frames, mirrored
clips with ``mirror``), truncated backpropagation through time in windows of
``window`` frames with the GRU's state carried over, and the same held-out
evaluation (:func:`~loosefit.train.motion.evaluate_rollouts`). A run is a
folder like the other stages' (``config.json``, ``checkpoint.pt`` written
atomically, TensorBoard events, ``report.json/.md``, ``model.pt`` without the
optimizer); a virtual-bones run also keeps its skinning decomposition
(``ssdr.npz``), computed once. ``loosefit animate`` and ``loosefit evaluate``
take a ``model.pt``/``checkpoint.pt`` of either.
"""

from __future__ import annotations

import resource
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch

from loosefit.data.format import DatasetReader, write_json_atomic
from loosefit.errors import LoosefitInputError
from loosefit.eval.rollouts import evaluate_rollouts
from loosefit.geometry.skinning import root_frame_transforms
from loosefit.inference.animator import BaselineModel, arm_collision_of, load_baseline
from loosefit.inference.checkpoints import (
    BASELINE_FORMAT,
    garment_record,
    read_checkpoint_file,
    save_atomic,
)
from loosefit.model.baselines import (
    BaselineConfig,
    BaselineLossConfig,
    BaselineNetwork,
    baseline_loss,
    body_joint_weights,
)
from loosefit.model.motion_features import feature_joints, num_features
from loosefit.model.rollout import RolloutConfig, Stages
from loosefit.train.common import (
    apply_overrides,
    epoch_means,
    machine,
    open_run,
    optimizer_step,
    restore_training,
)
from loosefit.train.frames import avatar_for
from loosefit.train.motion import Clip, pad_frames, prepare_clips

CHECKPOINT_FORMAT = BASELINE_FORMAT


@dataclass
class TrainBaselineConfig:
    """One training run of a baseline."""

    model: BaselineConfig = field(default_factory=BaselineConfig)
    loss: BaselineLossConfig = field(default_factory=BaselineLossConfig)
    rollout: RolloutConfig = field(default_factory=RolloutConfig)
    epochs: int = 300
    batch_size: int = 1  # clips side by side
    window: int = 50  # frames of truncated backpropagation through time
    lr: float = 1.0e-4
    weight_decay: float = 1.0e-3
    grad_clip: float = 10.0
    mirror: bool = False  # also the training clips mirrored (as the motion encoder's option)
    near: float = 0.02  # santesteban: m; vertices farther from the body get diffused weights
    ssdr_iterations: int = 30  # virtual-bones: Dem Bones' global iterations
    checkpoint_every: int = 5  # epochs
    eval_every: int = 10  # epochs; held-out rollout RMSE into TensorBoard
    max_frames: int | None = None  # per clip, for quick runs
    seed: int = 0
    device: str = "cpu"

    @classmethod
    def preset(cls, name: str, **overrides) -> TrainBaselineConfig:
        """``full`` (the motion encoder's: 300 epochs, batch 1, lr 1e-4) or ``cpu`` (40
        epochs, 16 clips side by side, lr 1e-3: the motion encoder's ``cpu`` preset with
        the 40 epochs the committed motion stage was trained for)."""
        model = {k: overrides.pop(k) for k in ("method", "bones", "joints") if k in overrides}
        model = {k: v for k, v in model.items() if v is not None}
        if name == "full":
            cfg = cls(model=BaselineConfig(**model))
        elif name == "cpu":
            cfg = cls(
                model=BaselineConfig(**model),
                epochs=40,
                batch_size=16,
                lr=1.0e-3,
                checkpoint_every=2,
                eval_every=10,
            )
        else:
            raise LoosefitInputError("--preset", "preset", "full or cpu", repr(name))
        return apply_overrides(cfg, overrides)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> TrainBaselineConfig:
        d = dict(d)
        d["model"] = BaselineConfig(**d["model"])
        d["loss"] = BaselineLossConfig(**d["loss"])
        d["rollout"] = RolloutConfig(**d["rollout"])
        return cls(**d)


# -- checkpoints ----------------------------------------------------------------------------


def save_checkpoint(path: Path, network: BaselineNetwork, meta: dict, **state) -> None:
    """Write a checkpoint atomically."""
    save_atomic({"format": BASELINE_FORMAT, **meta, "model": network.state_dict(), **state}, path)


# -- the data ---------------------------------------------------------------------------------


def clip_joints(avatar, clip: Clip) -> torch.Tensor:
    """(T, J, 3, 4) the avatar's rest -> root-frame joint transforms of a clip's motion frames."""
    world = avatar.pose_motion(clip.motion).joint_transforms.float().cpu()
    P = clip.preroll
    return root_frame_transforms(world, clip.heading[P:], clip.origin[P:])


def skinning_setup(
    method: str,
    reader: DatasetReader,
    avatar,
    clips: list[Clip],
    config: TrainBaselineConfig,
    cache: Path,
    log=print,
):
    """The rest shape, weights (and mean bone transforms) a baseline skins with.

    Santesteban: the template on the avatar's joints
    (:func:`~loosefit.geometry.skin_transfer.garment_skin_weights`). Virtual bones:
    a Dem Bones decomposition of every training frame in the root frame, cached in
    ``cache``; its rigid per-frame bone transforms are the bone network's targets.

    Returns:
        rest (V, 3), weights (V, K), bone_mean (K, 3, 4) or None, and per clip the extra
        per-frame tensor (joint transforms, or the fitted bone transforms).
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
        return torch.from_numpy(template.vertices), torch.from_numpy(weights), None, extra
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
    return torch.from_numpy(decomp.rest), torch.from_numpy(decomp.weights), mean, extra


def stack_clips(clips: list[Clip], extra: list[torch.Tensor]) -> dict[str, torch.Tensor]:
    """Clips side by side, padded to the longest (their last frame repeated)."""
    L = max(c.length for c in clips)
    T = max(c.target.shape[0] for c in clips)
    return {
        "features": torch.stack([pad_frames(c.features, L) for c in clips]),  # (B, L, F)
        "target": torch.stack([pad_frames(c.target, T) for c in clips]),  # (B, T, V, 3)
        "extra": torch.stack([pad_frames(x, T) for x in extra]),  # (B, T, K, 3, 4)
        "preroll": torch.tensor([c.preroll for c in clips]),
        "length": torch.tensor([c.length for c in clips]),
    }


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


# -- training ---------------------------------------------------------------------------------


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
        out: the run folder; an existing run with the same configuration resumes.
        config: the run (``config.model.method`` picks the baseline).
        log: where progress lines go.
        progress: show a tqdm bar.

    Returns:
        The report (also ``out/report.json`` and ``out/report.md``).
    """
    from torch.utils.tensorboard import SummaryWriter
    from tqdm import tqdm

    out = Path(out)
    reader = DatasetReader(data)
    template = reader.template
    method = config.model.method
    ckpt_path = out / "checkpoint.pt"
    open_run(out, {"dataset": str(Path(data).resolve()), "train": config.to_dict()})
    torch.manual_seed(config.seed)
    gen = torch.Generator().manual_seed(config.seed)
    floor = float(reader.body["floor_height"])
    avatar = avatar_for(reader)
    t0 = time.perf_counter()
    clips = prepare_clips(
        reader,
        "train",
        None,
        floor,
        config.rollout,
        config.max_frames,
        config.mirror,
        config.model.joints,
    )
    rest, weights, bone_mean, extra = skinning_setup(
        method, reader, avatar, clips, config, out / "ssdr.npz", log
    )
    log(
        f"prepared {len(clips)} train clips ({sum(c.length for c in clips)} frames) "
        f"in {time.perf_counter() - t0:.1f} s"
    )
    feats = torch.cat([c.features for c in clips])
    joint_names = clips[0].motion.joint_names
    F = feats.shape[1]
    expected = num_features(len(feature_joints(joint_names, config.model.joints)) + 1)
    if F != expected:
        raise LoosefitInputError(reader.root, "features", expected, F)
    network = BaselineNetwork(
        config.model, F, rest, weights, feats.mean(0), feats.std(0), bone_mean
    ).to(config.device)
    optim = torch.optim.Adam(network.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    meta = {
        "model_config": {"network": asdict(config.model), "rollout": asdict(config.rollout)},
        "config": config.to_dict(),
        "garment": garment_record(template),
        "num_features": F,
        "influences": int(weights.shape[1]),
        "joint_names": list(joint_names),
        "floor_height": floor,
        "fps": clips[0].motion.fps,
        "body": dict(reader.body),
        "cloth": reader.manifest.get("config", {}).get("cloth"),
        "dataset": str(Path(data).resolve()),
    }
    epoch, history = 0, []
    if ckpt_path.is_file():
        saved = read_checkpoint_file(ckpt_path, BASELINE_FORMAT, config.device)
        epoch, history = restore_training(saved, {"model": network, "optimizer": optim}, gen)
        log(f"resumed {ckpt_path} at epoch {epoch}")

    arms = arm_collision_of(meta)

    def current() -> BaselineModel:
        return BaselineModel(
            network,
            template,
            tuple(joint_names),
            floor,
            meta["fps"],
            dict(reader.body),
            config.rollout,
            ckpt_path,
            arm_collision=arms,
        )

    writer = SummaryWriter(str(out))
    bar = tqdm(
        total=config.epochs,
        initial=epoch,
        desc=f"train {method}",
        unit="epoch",
        disable=not progress,
    )
    t_start, epochs_run = time.perf_counter(), 0
    while epoch < config.epochs:
        network.train()
        order = torch.randperm(len(clips), generator=gen).tolist()
        sums: dict[str, float] = {}
        steps = 0
        for b in range(0, len(order), config.batch_size):
            pick = order[b : b + config.batch_size]
            batch = {
                k: v.to(config.device)
                for k, v in stack_clips([clips[i] for i in pick], [extra[i] for i in pick]).items()
            }
            hidden = network.initial_hidden(len(pick), config.device)
            L = int(batch["length"].max())
            for start in range(0, L, config.window):
                terms, hidden = run_window(
                    network, batch, start, min(start + config.window, L), hidden, config.loss
                )
                if terms is None:
                    continue
                optimizer_step(optim, network.parameters(), terms, config.grad_clip, sums)
                steps += 1
        sums = epoch_means(sums, steps, epoch)
        epoch += 1
        epochs_run += 1
        history.append({"epoch": epoch, **sums})
        for k, v in sums.items():
            writer.add_scalar(f"loss/{k}", v, epoch)
        bar.set_postfix(loss=f"{sums.get('total', float('nan')):.3g}")
        bar.update(1)
        if epoch % config.checkpoint_every == 0 or epoch == config.epochs:
            save_checkpoint(
                ckpt_path,
                network,
                meta,
                optimizer=optim.state_dict(),
                epoch=epoch,
                history=history,
                rng=torch.get_rng_state(),
                sampling_rng=gen.get_state(),
            )
        if epoch % config.eval_every == 0 or epoch == config.epochs:
            raw = Stages(detail=False, lengths=False, collision=False)
            err = evaluate_rollouts(current(), reader, "test", surface=False, stages=raw)
            writer.add_scalar("test/rollout_rmse_cm", err["rmse_cm"], epoch)
            history[-1]["test_rollout_rmse_cm"] = err["rmse_cm"]
            bar.write(f"epoch {epoch}: held-out rollout RMSE {err['rmse_cm']:.2f} cm")
    bar.close()
    seconds = time.perf_counter() - t_start
    save_checkpoint(out / "model.pt", network, meta, epoch=epoch)
    model = load_baseline(out / "model.pt", config.device)
    report = {
        "method": method,
        "dataset": str(Path(data).resolve()),
        "epochs": config.epochs,
        "parameters": sum(p.numel() for p in network.parameters()),
        "seconds_per_epoch": seconds / epochs_run if epochs_run else None,
        "peak_memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "machine": machine(config.device),
        "final_loss": history[-1] if history else None,
        "test": evaluate_rollouts(
            model, reader, "test", stages=Stages(detail=False, lengths=False, collision=False)
        ),
    }
    write_json_atomic(out / "report.json", report)
    (out / "report.md").write_text(format_report(report))
    writer.close()
    return report


def format_report(report: dict) -> str:
    """A Markdown summary of a baseline run's report."""
    t = report["test"]
    spe = report.get("seconds_per_epoch")
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
            f"{report['parameters']:,} parameters; "
            + (f"{spe:.2f} s per epoch; " if spe else "")
            + f"peak memory {report['peak_memory_mb']:.0f} MB; {report['machine']}.",
            "",
        ]
    )
