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
"""

from __future__ import annotations

import hashlib
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
from loosefit.eval.metrics import hausdorff, rmse_per_frame, sted
from loosefit.geometry.collision import BodyCollider, CollisionConfig, CollisionHandler
from loosefit.geometry.laplacian import Laplacian
from loosefit.model.frames import avatar_for, garment_fingerprint, to_root_frame
from loosefit.model.generative import GarmentGenerativeModel, squared_error
from loosefit.model.motion_encoder import DynamicMotionEncoder, MotionEncoderConfig
from loosefit.model.motion_features import (
    feature_joints,
    motion_features,
    num_features,
    root_frames,
)
from loosefit.model.rollout import (
    MOTION_ONLY,
    RolloutConfig,
    Stages,
    carried_drape,
    change_frame,
    latent_codes,
    reconstruction,
    rollout,
    timeline,
)
from loosefit.train.common import (
    apply_overrides,
    epoch_means,
    machine,
    open_run,
    optimizer_step,
    read_checkpoint_file,
    recorded_checkpoint,
    restore_training,
    save_atomic,
    template_dict,
    template_from_dict,
)
from loosefit.train.generative import load_checkpoint as load_generative
from loosefit.types import GarmentTemplate, Motion

CHECKPOINT_FORMAT = "loosefit.motion/1"
HORIZONS = (100, 500, 1200)  # the paper's Table 1: iter-100, iter-500, iter-1200


@dataclass
class MotionLossConfig:
    """Eqs. 10-12 and the length unit of the geometry terms."""

    laplacian: float = 1.5  # lambda_4
    latent: float = 0.5  # lambda_5
    length_scale: float = 100.0  # metres to centimetres, as in the generative loss


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

    def __post_init__(self) -> None:
        if self.previous not in ("scheduled", "teacher"):
            raise LoosefitInputError("TrainMotionConfig", "previous", "scheduled or teacher",
                                     repr(self.previous))  # fmt: skip
        if not (0.0 <= self.teacher_end <= self.teacher_start <= 1.0):
            raise LoosefitInputError("TrainMotionConfig", "teacher_start, teacher_end",
                                     "0 <= teacher_end <= teacher_start <= 1",
                                     (self.teacher_start, self.teacher_end))  # fmt: skip
        for name in ("unroll", "mirror"):
            if not isinstance(getattr(self, name), bool):
                raise LoosefitInputError("TrainMotionConfig", name, "true or false",
                                         repr(getattr(self, name)))  # fmt: skip
        if not self.previous_noise >= 0:
            raise LoosefitInputError("TrainMotionConfig", "previous_noise", "metres >= 0",
                                     self.previous_noise)  # fmt: skip
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
    names = reader.split(split)
    if not names:
        raise LoosefitInputError(reader.root, f"split '{split}'", "at least one clip", "none")
    twins = vertex_twins(reader.template.vertices) if mirror else None
    clips = []
    for name in names:
        seq = reader.read(name)
        motion = seq.motion if max_frames is None else seq.motion.slice(0, max_frames)
        garment = seq.garment_vertices[: motion.num_frames]
        versions = [(name, motion, garment)]
        if mirror:
            versions.append((f"{name}~mirror", mirror_motion(motion),
                             mirror_garment(garment, twins)))  # fmt: skip
        for label, m, v in versions:
            rot, root, P = timeline(m, floor_height, config)
            H, p = (a.float() for a in root_frames(rot.double(), root.double()))
            target = to_root_frame(torch.from_numpy(np.ascontiguousarray(v, np.float32)),
                                   H[P:], p[P:])  # fmt: skip
            feats = motion_features(rot, root, m.fps, floor_height,
                                    feature_joints(m.joint_names, joints))  # fmt: skip
            clips.append(Clip(label, m, feats,
                              H, p, target,
                              None if generative is None else latent_codes(generative, target),
                              P))  # fmt: skip
    return clips


def rest_state_for(reader: DatasetReader, fps: float) -> torch.Tensor:
    """(V, 3) the settled drape of the dataset's garment (its cloth configuration)."""
    from loosefit.sim.cloth import ClothConfig, settle

    cloth = reader.manifest.get("config", {}).get("cloth")
    if cloth is None:
        raise LoosefitInputError(
            reader.root / "manifest.json", "config.cloth", "the cloth configuration of the "
            "simulation (to settle the garment where rollouts start)", "none",
        )  # fmt: skip
    cloth = dict(cloth)
    cloth["device"] = "cpu"
    return torch.from_numpy(settle(avatar_for(reader), reader.template, ClothConfig(**cloth), fps))


# -- fingerprints and checkpoints ----------------------------------------------------


def model_fingerprint(model: torch.nn.Module) -> str:
    """A short hash of a model's weights, rounded to half precision (as shared checkpoints are)."""
    h = hashlib.sha256()
    for k, v in sorted(model.state_dict().items()):
        h.update(k.encode())
        h.update(v.detach().cpu().half().numpy().tobytes() if v.is_floating_point()
                 else v.detach().cpu().numpy().tobytes())  # fmt: skip
    return h.hexdigest()[:16]


def save_checkpoint(path: Path, encoder: DynamicMotionEncoder, meta: dict, half: bool = False,
                    **state) -> None:  # fmt: skip
    """Write a checkpoint atomically; ``half`` stores floating weights in half precision."""
    weights = {
        k: (v.half() if half and v.is_floating_point() else v)
        for k, v in encoder.state_dict().items()
    }
    save_atomic({"format": CHECKPOINT_FORMAT, **meta, "model": weights, **state}, path)


def _read(path: Path, device) -> dict:
    return read_checkpoint_file(path, CHECKPOINT_FORMAT, device, {
        "loosefit.generative/1": "this is the generative stage; pass the motion stage's checkpoint"
    })  # fmt: skip


def check_motion_joints(motion: Motion, joint_names: tuple[str, ...], path: Path) -> None:
    """A clear error for a motion on other joints than a checkpoint's, or not finite."""
    if tuple(motion.joint_names) != tuple(joint_names):
        missing = [j for j in joint_names if j not in motion.joint_names]
        raise LoosefitInputError(
            f"motion '{motion.name}'", "joint_names",
            f"the {len(joint_names)} joints the checkpoint {Path(path).name} was "
            "trained on, in its order",
            f"{len(motion.joint_names)} joints" + (f", missing {missing[:5]}" if missing
                                                   else ", in another order"),
        )  # fmt: skip
    if not np.isfinite(motion.rotations).all() or not np.isfinite(motion.root_translation).all():
        raise LoosefitInputError(f"motion '{motion.name}'", "rotations/root_translation",
                                 "finite numbers", "NaN or infinity")  # fmt: skip


def body_collider(avatar, handler, motion: Motion, arm_collision: bool, device: torch.device
                  ) -> BodyCollider:  # fmt: skip
    """``handler`` (Eq. 16's, or a baseline's push-out) along ``motion``'s posed body, the
    simulation's collider (the arms in it only with ``arm_collision``)."""
    rot = torch.from_numpy(motion.rotations)
    root = torch.from_numpy(motion.root_translation)

    def pose(start: int, stop: int) -> np.ndarray:
        return avatar.pose(rot[start:stop], root[start:stop]).vertices.cpu().numpy()

    faces = avatar.collider_faces(arms=arm_collision).cpu().numpy()
    warp_device = "cpu" if device.type == "cpu" else f"cuda:{device.index or 0}"
    return BodyCollider(handler, faces, pose, motion.num_frames, device=warp_device)


def avatar_of(body: dict):
    """The avatar of a checkpoint's ``body`` record (its shape)."""
    from loosefit.body.avatar import Avatar, AvatarConfig

    return Avatar(AvatarConfig(shape=dict(body.get("shape", {}))))


@dataclass
class AnimationModel:
    """Everything a rollout needs, loaded from a motion-stage checkpoint."""

    generative: GarmentGenerativeModel
    encoder: DynamicMotionEncoder
    template: GarmentTemplate
    rest_state: torch.Tensor  # (V, 3)
    joint_names: tuple[str, ...]
    floor_height: float
    fps: float
    body: dict
    config: TrainMotionConfig
    path: Path
    detail: torch.nn.Module | None = None  # paper 3.4 (a DetailGenerator), if trained
    collision: CollisionConfig = field(default_factory=CollisionConfig)  # paper 3.5
    arm_collision: bool = False  # the arms in the collider (as in the simulation of the data)
    stages: Stages = field(default_factory=Stages)  # what animate() runs by default
    _avatar: object = None
    _handler: CollisionHandler | None = None

    @property
    def device(self) -> torch.device:
        return self.rest_state.device

    def avatar(self):
        """The body the garment was simulated on (built once)."""
        if self._avatar is None:
            self._avatar = avatar_of(self.body)
        return self._avatar

    def collider(self, motion: Motion) -> BodyCollider:
        """Collision handling (paper 3.5) along ``motion``'s frames (the simulation's collider)."""
        if self._handler is None:
            t = self.template
            self._handler = CollisionHandler(t.faces, t.num_vertices, self.collision)
        return body_collider(self.avatar(), self._handler, motion, self.arm_collision,
                             self.device)  # fmt: skip

    def check_motion(self, motion: Motion) -> None:
        """A clear error for a motion on other joints or at another frame rate."""
        check_motion_joints(motion, self.joint_names, self.path)

    def animate(self, motion: Motion, progress=None, truth=None, restart_every=None,
                stages: Stages | None = None):  # fmt: skip
        """:func:`~loosefit.model.rollout.rollout` of ``motion`` (checked first) through the
        motion stage, then the detail stage (if the model has one) and collision handling,
        as ``stages`` (default ``self.stages``) says."""
        self.check_motion(motion)
        stages = stages or self.stages
        detail = self.detail if stages.detail else None
        collide = self.collider(motion) if stages.collision else None
        return rollout(self.generative, self.encoder, motion, self.rest_state,
                       self.floor_height, self.config.rollout, progress, truth,
                       restart_every, detail, collide, stages.feedback,
                       stages.overlap)  # fmt: skip

    def carry_drape(self, motion: Motion, progress=None):
        """:func:`~loosefit.model.rollout.carried_drape`: this garment with no dynamics."""
        self.check_motion(motion)
        return carried_drape(motion, self.rest_state, self.floor_height, self.config.rollout)

    def reconstruct(self, motion: Motion, truth: np.ndarray):
        """:func:`~loosefit.model.rollout.reconstruction`: the floor under the encoder's error."""
        self.check_motion(motion)
        return reconstruction(self.generative, motion, truth, self.floor_height,
                              self.config.rollout)  # fmt: skip


def load_animation_model(
    path: str | Path, generative: str | Path | None = None, device="cpu"
) -> AnimationModel:
    """The generative and motion stages of a trained model.

    Args:
        path: a motion-stage checkpoint (``checkpoint.pt`` or ``model.pt`` of a run).
        generative: the generative-stage checkpoint it was trained on; by default
            the one it records (relative to ``path``'s folder, then absolute).
        device: where to put the networks.

    Raises:
        LoosefitInputError: not a motion-stage checkpoint, a missing generative
            checkpoint, or one other than the encoder was trained on.
    """
    path = Path(path)
    data = _read(path, device)
    g = data["generative"]
    gpath = recorded_checkpoint(
        path,
        g,
        generative,
        "generative",
        "the generative checkpoint it was trained on",
        "pass --generative FILE",
    )
    gmodel, _, _ = load_generative(gpath, device=device)
    found = model_fingerprint(gmodel)
    if found != g["fingerprint"]:
        raise LoosefitInputError(
            gpath, "model", f"the generative model {path.name} was trained on "
            f"(fingerprint {g['fingerprint']})", f"another one (fingerprint {found})",
        )  # fmt: skip
    template = template_from_dict(data["garment"]["template"])
    config = TrainMotionConfig.from_dict(data["config"])
    encoder = DynamicMotionEncoder(gmodel, data["num_features"], config.model).to(device)
    try:
        encoder.load_state_dict({k: v.float() if v.is_floating_point() else v
                                 for k, v in data["model"].items()})  # fmt: skip
    except RuntimeError as exc:
        raise LoosefitInputError(path, "model", "weights of this model's configuration",
                                 str(exc).splitlines()[0]) from exc  # fmt: skip
    for p in gmodel.parameters():
        p.requires_grad_(False)
    return AnimationModel(
        gmodel.eval(), encoder.eval(), template,
        torch.as_tensor(data["rest_state"]).float().to(device),
        tuple(data["joint_names"]), float(data["floor_height"]), float(data["fps"]),
        dict(data["body"]), config, path,
        arm_collision=bool((data.get("cloth") or {}).get("arm_collision", False)),
    )  # fmt: skip


def _half(weights: dict) -> dict:
    return {k: (v.half() if v.is_floating_point() else v) for k, v in weights.items()}


def package_model(
    path: str | Path, out: str | Path, generative: str | Path | None = None
) -> tuple[Path, Path]:
    """Both stages of a trained model in one folder, for sharing: weights only, half precision.

    Writes ``out/generative.pt`` (the generative stage without its optimizer state)
    and ``out/motion.pt`` (the motion stage, pointing at ``generative.pt`` beside it
    by a relative path, and at no path of this machine). The fingerprint that ties
    them is of half-precision weights, so the pair loads as the original did.

    Args:
        path: a motion-stage checkpoint (``model.pt`` or ``checkpoint.pt`` of a run).
        out: the folder to write.
        generative: its generative checkpoint, if not the one it records.

    Returns:
        The paths of the generative and the motion files.
    """
    from loosefit.train.generative import read_checkpoint as read_generative

    path, out = Path(path), Path(out)
    load_animation_model(path, generative)  # checks the pair belongs together
    data = _read(path, "cpu")
    gpath = recorded_checkpoint(
        path,
        data["generative"],
        generative,
        "generative",
        "the generative checkpoint it was trained on",
        "pass --generative FILE",
    )
    gdata, _ = read_generative(gpath)
    out.mkdir(parents=True, exist_ok=True)
    gout, mout = out / "generative.pt", out / "motion.pt"
    keep = ("format", "config", "garment", "epoch")
    save_atomic({**{k: gdata[k] for k in keep if k in gdata}, "model": _half(gdata["model"])},
                gout)  # fmt: skip
    drop = ("optimizer", "rng", "sampling_rng", "history", "dataset")
    motion = {k: v for k, v in data.items() if k not in drop}
    motion["model"] = _half(data["model"])
    motion["generative"] = {**data["generative"], "relative": gout.name, "absolute": None}
    save_atomic(motion, mout)
    return gout, mout


# -- evaluation ------------------------------------------------------------------------


def evaluate_rollouts(
    model: AnimationModel,
    reader: DatasetReader,
    split: str = "test",
    horizons: tuple[int, ...] = HORIZONS,
    surface: bool = True,
    max_frames: int | None = None,
    reference: bool = False,
    restart_every: int | None = None,
    oracle: bool = False,
    stages: Stages | None = None,
) -> dict:
    """Roll every clip of a split out from its first frame and compare with the simulation.

    Args:
        model: the trained stages.
        reader: the dataset.
        split: "train", "test" or "all".
        horizons: report the RMSE over the first h frames for each h (the paper's
            iter-100/500/1200); a clip shorter than h gives none for it.
        surface: also Hausdorff and STED (slower).
        max_frames: roll out at most this many frames per clip.
        reference: score the settled drape carried by the root
            (:meth:`AnimationModel.carry_drape`) instead of the model's rollout.
        restart_every: reset the rollout's previous state to the simulated garment
            every this many frames (:func:`~loosefit.model.rollout.rollout`'s
            ``truth``), to measure drift on the same frames.
        oracle: score the generative model's reconstruction of the simulated
            garment (:meth:`AnimationModel.reconstruct`) instead: the floor under
            the motion encoder's error.
        stages: the stages after the decoders (default: the model's, all of them).

    Returns:
        Per clip: frames, RMSE (cm) over the clip and per horizon, the RMSE of
        every frame (cm), Hausdorff (cm, mean over frames), STED, frames per
        second; and frame-weighted means over the clips.
    """
    faces = reader.template.faces
    clips = {}
    for name in reader.split(split):
        seq = reader.read(name)
        motion = seq.motion if max_frames is None else seq.motion.slice(0, max_frames)
        true = seq.garment_vertices[: motion.num_frames]
        if reference:
            result = model.carry_drape(motion)
        elif oracle:
            result = model.reconstruct(motion, true)
        elif restart_every is not None:
            result = model.animate(motion, truth=true, restart_every=restart_every,
                                   stages=stages)  # fmt: skip
        else:
            result = model.animate(motion, stages=stages)
        pred = result.vertices
        per_frame = 100 * rmse_per_frame(pred, true)  # (T,) cm
        entry = {
            "frames": int(len(pred)),
            "rmse_cm": float(np.sqrt(np.mean(per_frame**2))),
            "horizons": {
                str(h): float(np.sqrt(np.mean(per_frame[:h] ** 2)))
                for h in horizons if len(pred) >= h
            },
            "rmse_per_frame_cm": per_frame.tolist(),
            "frames_per_second": result.frames_per_second,
        }  # fmt: skip
        if surface:
            entry["hausdorff_cm"] = 100 * float(hausdorff(pred, true, faces).mean())
            entry["sted"] = sted(pred, true, faces, motion.fps)["sted"] if len(pred) > 1 else 0.0
        clips[name] = entry
    n = np.array([c["frames"] for c in clips.values()], float)

    def mean(key: str) -> float:
        return float((np.array([c[key] for c in clips.values()]) * n).sum() / n.sum())

    summary = {"frames": int(n.sum()), "rmse_cm": float(np.sqrt(
        sum(c["rmse_cm"] ** 2 * c["frames"] for c in clips.values()) / n.sum()))}  # fmt: skip
    if surface:
        summary.update(hausdorff_cm=mean("hausdorff_cm"), sted=mean("sted"))
    summary["horizons"] = {}
    for h in horizons:
        have = [c for c in clips.values() if str(h) in c["horizons"]]
        if have:
            summary["horizons"][str(h)] = float(np.sqrt(np.mean([c["horizons"][str(h)] ** 2
                                                                 for c in have])))  # fmt: skip
    return {"split": split, "clips": clips, **summary}


# -- training --------------------------------------------------------------------------


def pad_frames(x: torch.Tensor, n: int) -> torch.Tensor:
    """Frames (T, ...) padded to ``n`` by repeating the last (clips stacked side by side)."""
    return torch.cat([x, x[-1:].expand(n - len(x), *x.shape[1:])]) if len(x) < n else x


def _stack(clips: list[Clip]) -> dict[str, torch.Tensor]:
    """Clips side by side, padded to the longest by repeating their last frame."""
    L = max(c.length for c in clips)
    T = max(c.target.shape[0] for c in clips)

    return {
        "features": torch.stack([pad_frames(c.features, L) for c in clips]),  # (B, L, F)
        "heading": torch.stack([pad_frames(c.heading, L) for c in clips]),
        "origin": torch.stack([pad_frames(c.origin, L) for c in clips]),
        "target": torch.stack([pad_frames(c.target, T) for c in clips]),  # (B, T, V, 3)
        "latent": torch.stack([pad_frames(c.latent, T) for c in clips]),
        "preroll": torch.tensor([c.preroll for c in clips]),
        "length": torch.tensor([c.length for c in clips]),
    }


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
) -> tuple[dict[str, torch.Tensor], torch.Tensor, torch.Tensor]:
    """Frames ``start:stop`` of stacked clips: the loss and the state to carry on.

    Args:
        encoder, generative, laplacian: the networks (the generative one frozen).
        batch: :func:`_stack` of B clips.
        start, stop: the window, on the rollout timeline.
        hidden: (B, gru) the GRU state after frame ``start - 1`` (detached here).
        previous: (B, V, 3) the garment of frame ``start - 1`` in its root frame.
        teacher: the chance that a frame's previous state is the ground truth.
        loss: the weights.
        generator: draws the teacher choices (and the noise).
        noise: std (m) of Gaussian noise added to a ground-truth previous state.
        unroll: keep the encoder's own prediction, fed back as the next frame's
            previous state, in the graph (within this window; it is detached at the
            window's start like the GRU state).

    Returns:
        The loss terms (means over the window's valid frames; ``total``
        differentiable w.r.t. the encoder through this window only), the detached
        GRU state and the previous garment for the next window.
    """
    s = loss.length_scale
    B = hidden.shape[0]
    hidden = hidden.detach()
    previous = previous.detach()
    P, length = batch["preroll"], batch["length"]
    H, p = batch["heading"], batch["origin"]
    sums = {"geometry": 0.0, "laplacian": 0.0, "latent": 0.0}
    count = 0
    for t in range(start, stop):
        if t > 0:
            previous = change_frame(previous, H[:, t - 1], p[:, t - 1], H[:, t], p[:, t])
        z, hidden = encoder(batch["features"][:, t], previous, hidden)
        v = generative.decode(z)["vertices"]
        m = t - P  # (B,) motion frame
        valid = (m >= 0) & (t < length)
        k = m.clamp(0, batch["target"].shape[1] - 1)
        if valid.any():
            rows = torch.arange(B)[valid]
            vt, zt = batch["target"][rows, k[valid]], batch["latent"][rows, k[valid]]
            vp, zp = v[valid], z[valid]
            n = int(valid.sum())
            sums["geometry"] = sums["geometry"] + n * squared_error(s * vp, s * vt)
            sums["laplacian"] = sums["laplacian"] + n * loss.laplacian * squared_error(
                s * laplacian(vp), s * laplacian(vt)
            )
            sums["latent"] = sums["latent"] + n * loss.latent * (zp - zt).pow(2).sum(-1).mean()
            count += n
        previous = v if unroll else v.detach()
        if teacher > 0:
            use = (torch.rand(B, generator=generator) < teacher) & valid
            if use.any():
                gt = batch["target"][torch.arange(B), k]
                if noise > 0:
                    gt = gt + noise * torch.randn(gt.shape, generator=generator)
                previous = torch.where(use[:, None, None], gt, previous)
    terms = {k: v / max(count, 1) for k, v in sums.items()}
    terms = {k: (v if torch.is_tensor(v) else torch.tensor(v)) for k, v in terms.items()}
    terms["total"] = terms["geometry"] + terms["laplacian"] + terms["latent"]
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
    gpath = Path(generative).resolve()
    gmodel, _, _ = load_generative(gpath, template, config.device)
    for prm in gmodel.parameters():
        prm.requires_grad_(False)
    gmeta = {
        "relative": os.path.relpath(gpath, out.resolve()),
        "absolute": str(gpath),
        "fingerprint": model_fingerprint(gmodel),
    }
    ckpt_path = out / "checkpoint.pt"
    open_run(out, {"dataset": str(Path(data).resolve()), "generative": gmeta["fingerprint"],
                   "train": config.to_dict()})  # fmt: skip

    torch.manual_seed(config.seed)
    gen = torch.Generator().manual_seed(config.seed)
    floor = float(reader.body["floor_height"])
    t0 = time.perf_counter()
    train = prepare_clips(reader, "train", gmodel, floor, config.rollout, config.max_frames,
                          config.mirror, config.model.joints)  # fmt: skip
    fps = train[0].motion.fps
    rest_path = out / "rest_state.npy"
    if rest_state is not None:
        rest = torch.as_tensor(rest_state).float()
    elif rest_path.is_file():
        rest = torch.from_numpy(np.load(rest_path))
    else:
        rest = rest_state_for(reader, fps)
        np.save(rest_path, rest.numpy())
    log(f"prepared {len(train)} train clips ({sum(c.length for c in train)} frames) "
        f"in {time.perf_counter() - t0:.1f} s")  # fmt: skip
    all_feats = torch.cat([c.features for c in train])
    F = all_feats.shape[1]
    joint_names = train[0].motion.joint_names
    expected = num_features(len(feature_joints(joint_names, config.model.joints)) + 1)
    if F != expected:
        raise LoosefitInputError(reader.root, "features", expected, F)
    encoder = DynamicMotionEncoder(gmodel, F, config.model, all_feats.mean(0), all_feats.std(0))
    encoder.to(config.device)
    lap = Laplacian(template.faces, template.num_vertices).to(config.device)
    optim = torch.optim.Adam(encoder.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    meta = {
        "config": config.to_dict(),
        "generative": gmeta,
        "garment": {
            "fingerprint": garment_fingerprint(template.vertices, template.faces),
            "template": template_dict(template),
        },  # fmt: skip
        "num_features": F,
        "joint_names": list(joint_names),
        "floor_height": floor,
        "fps": fps,
        "body": dict(reader.body),
        "rest_state": rest.numpy(),
        "cloth": reader.manifest.get("config", {}).get("cloth"),  # the physics of the data
        "dataset": str(Path(data).resolve()),
    }
    epoch, history = 0, []
    if ckpt_path.is_file():
        epoch, history = restore_training(
            _read(ckpt_path, config.device), {"model": encoder, "optimizer": optim}, gen
        )
        log(f"resumed {ckpt_path} at epoch {epoch}")

    writer = SummaryWriter(str(out))
    bar = tqdm(total=config.epochs, initial=epoch, desc="train motion encoder", unit="epoch",
               disable=not progress)  # fmt: skip
    t_start, epochs_run = time.perf_counter(), 0
    while epoch < config.epochs:
        encoder.train()
        teacher = config.teacher_probability(epoch)
        order = torch.randperm(len(train), generator=gen).tolist()
        sums: dict[str, float] = {}
        steps = 0
        for b in range(0, len(order), config.batch_size):
            batch = _stack([train[i] for i in order[b : b + config.batch_size]])
            B = len(batch["length"])
            hidden = encoder.initial_hidden(B)
            previous = rest[None].expand(B, -1, -1).clone()
            for start in range(0, int(batch["length"].max()), config.window):
                stop = min(start + config.window, int(batch["length"].max()))
                terms, hidden, previous = run_window(
                    encoder, gmodel, lap, batch, start, stop, hidden, previous, teacher,
                    config.loss, gen, config.previous_noise, config.unroll,
                )  # fmt: skip
                if not terms["total"].requires_grad:
                    continue  # a window with no motion frame (all preroll)
                optimizer_step(optim, encoder.parameters(), terms, config.grad_clip, sums)
                steps += 1
        sums = epoch_means(sums, steps, epoch)
        epoch += 1
        epochs_run += 1
        history.append({"epoch": epoch, "teacher": teacher, **sums})
        for k, v in sums.items():
            writer.add_scalar(f"loss/{k}", v, epoch)
        writer.add_scalar("train/teacher_probability", teacher, epoch)
        bar.set_postfix(loss=f"{sums.get('total', float('nan')):.3g}", teacher=f"{teacher:.2f}")
        bar.update(1)
        if epoch % config.checkpoint_every == 0 or epoch == config.epochs:
            save_checkpoint(ckpt_path, encoder, meta, optimizer=optim.state_dict(), epoch=epoch,
                            history=history, rng=torch.get_rng_state(),
                            sampling_rng=gen.get_state())  # fmt: skip
        if epoch % config.eval_every == 0 or epoch == config.epochs:
            current = AnimationModel(gmodel, encoder, template, rest.to(config.device),
                                     tuple(joint_names), floor, fps, dict(reader.body), config,
                                     ckpt_path)  # fmt: skip
            err = evaluate_rollouts(current, reader, "test", surface=False, stages=MOTION_ONLY)
            writer.add_scalar("test/rollout_rmse_cm", err["rmse_cm"], epoch)
            history[-1]["test_rollout_rmse_cm"] = err["rmse_cm"]
            bar.write(f"epoch {epoch}: held-out rollout RMSE {err['rmse_cm']:.2f} cm")
    bar.close()
    seconds = time.perf_counter() - t_start
    save_checkpoint(out / "model.pt", encoder, meta, half=True, epoch=epoch)

    model = load_animation_model(out / "model.pt", gpath, config.device)
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
        lines.append(f"| {name} | {c['frames']} | {c['rmse_cm']:.3f} | " + " | ".join(cells)
                     + f" | {c['hausdorff_cm']:.3f} | {c['sted']:.4f} | "
                     f"{c['frames_per_second']:.0f} |")  # fmt: skip
    spe = report.get("seconds_per_epoch")
    lines += [
        "",
        f"{report['parameters']:,} parameters; "
        + (f"{spe:.1f} s per epoch; " if spe else "")
        + f"peak memory {report['peak_memory_mb']:.0f} MB; {report['machine']}.",
        "",
    ]
    return "\n".join(lines)
