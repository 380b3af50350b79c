"""Trained models that animate a garment: the paper's stages and the baselines.

:func:`load_pipeline` takes any checkpoint ``loosefit animate`` takes and gives a model
with ``animate(motion)``: :class:`AnimationModel` (paper 3.2-3.5) or :class:`BaselineModel`.
Models are rebuilt from the checkpoints' ``model_config``
(:mod:`loosefit.inference.checkpoints`); nothing here reads a training configuration.
"""

from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from loosefit.errors import LoosefitInputError
from loosefit.garment.fingerprint import garment_fingerprint
from loosefit.geometry.collision import (
    BodyCollider,
    CollisionConfig,
    CollisionHandler,
    PushOutHandler,
    collision_setting,
)
from loosefit.inference.checkpoints import (
    BASELINE_FORMAT,
    DETAIL_FORMAT,
    MOTION_FORMAT,
    checkpoint_fields,
    checkpoint_format,
    load_generative,
    load_weights,
    model_config,
    model_fingerprint,
    read_checkpoint_file,
    recorded_checkpoint,
    template_from_dict,
)
from loosefit.model.baselines import BaselineConfig, BaselineNetwork, baseline_rollout
from loosefit.model.detail import DetailConfig, DetailGenerator
from loosefit.model.generative import GarmentGenerativeModel
from loosefit.model.motion_encoder import DynamicMotionEncoder, MotionEncoderConfig
from loosefit.model.physics import (
    PHYSICS_TERMS,
    ClothStructure,
    LengthConfig,
    LengthRestorer,
    hanging_edges,
    terms_of,
)
from loosefit.model.rollout import (
    RolloutConfig,
    Stages,
    carried_drape,
    collision_record,
    reconstruction,
    refine,
    rollout,
    rollout_batch,
)
from loosefit.types import GarmentTemplate, Motion

RUNTIMES = ("torch", "onnx")  # what runs the learned stages: PyTorch, or onnxruntime


def check_runtime(runtime: str, source: str = "animate") -> None:
    """A clear error for a runtime other than :data:`RUNTIMES`."""
    if runtime not in RUNTIMES:
        raise LoosefitInputError(source, "runtime", " or ".join(map(repr, RUNTIMES)), repr(runtime))


def check_motion_joints(motion: Motion, joint_names: tuple[str, ...], path: Path) -> None:
    """A clear error for a motion on other joints than a checkpoint's, or not finite."""
    if tuple(motion.joint_names) != tuple(joint_names):
        missing = [j for j in joint_names if j not in motion.joint_names]
        raise LoosefitInputError(
            f"motion '{motion.name}'",
            "joint_names",
            f"the {len(joint_names)} joints the checkpoint {Path(path).name} was "
            "trained on, in its order",
            f"{len(motion.joint_names)} joints"
            + (f", missing {missing[:5]}" if missing else ", in another order"),
        )
    if not np.isfinite(motion.rotations).all() or not np.isfinite(motion.root_translation).all():
        raise LoosefitInputError(
            f"motion '{motion.name}'",
            "rotations/root_translation",
            "finite numbers",
            "NaN or infinity",
        )


def body_collider(
    avatar, handler, motion: Motion, arm_collision: bool | str, device: torch.device
) -> BodyCollider:
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


def arm_collision_of(data: dict, default: bool | str = False) -> bool | str:
    """The arms the cloth met as the data was simulated: False, True or "upper" (True also
    where they were a collider of their own, ``ClothConfig.arm_friction``; data made before
    that field existed had none); ``default`` where the configuration does not say."""
    cloth = data.get("cloth") or {}
    if cloth.get("arm_friction") is not None:
        return True
    arms = cloth.get("arm_collision", default)
    return arms if arms == "upper" else bool(arms)


# -- the paper's model ------------------------------------------------------------------------


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
    rollout_config: RolloutConfig
    path: Path
    detail: torch.nn.Module | None = None  # paper 3.4 (a DetailGenerator), if trained
    collision: CollisionConfig = field(default_factory=CollisionConfig)  # paper 3.5
    arm_collision: bool | str = False  # the arms in the collider, as the data's simulation
    stages: Stages = field(default_factory=Stages)  # what animate() runs by default
    lengths: LengthConfig = field(default_factory=LengthConfig)  # edges back to rest length
    physics_terms: tuple[str, ...] = ()  # the physics terms the stages were trained with
    trained_on: dict | None = None  # a packaged set's training record (package.training_record)
    _avatar: object = None
    _handler: CollisionHandler | None = None
    _restorer: LengthRestorer | None = None
    _onnx: object = None  # the learned stages in onnxruntime (OnnxStages), built once

    @property
    def device(self) -> torch.device:
        return self.rest_state.device

    def avatar(self):
        """The body the garment was simulated on (built once)."""
        if self._avatar is None:
            self._avatar = avatar_of(self.body)
        return self._avatar

    @contextmanager
    def configured(
        self, collision: CollisionConfig | None = None, lengths: LengthConfig | None = None
    ):
        """Within the block, collision handling and the edge-length stage configured as given
        (None: as they are), their operators built anew; after it, the model's own
        configurations and operators come back (a comparison of settings, in one model)."""
        saved = (self.collision, self._handler, self.lengths, self._restorer)
        if collision is not None:
            self.collision, self._handler = collision, None
        if lengths is not None:
            self.lengths, self._restorer = lengths, None
        try:
            yield self
        finally:
            self.collision, self._handler, self.lengths, self._restorer = saved

    def collider(self, motion: Motion) -> BodyCollider:
        """Collision handling (paper 3.5) along ``motion``'s frames (the simulation's collider)."""
        if self._handler is None:
            t = self.template
            self._handler = CollisionHandler(
                t.faces, t.num_vertices, self.collision, np.asarray(t.vertices, np.float64)
            )
        arms = True if self.collision.whole_body else self.arm_collision
        return body_collider(self.avatar(), self._handler, motion, arms, self.device)

    def check_motion(self, motion: Motion) -> None:
        """A clear error for a motion on other joints or at another frame rate."""
        check_motion_joints(motion, self.joint_names, self.path)

    @property
    def missing_physics_terms(self) -> tuple[str, ...]:
        """The physics terms (membrane, bending, collision) the stages were not trained with."""
        return tuple(t for t in PHYSICS_TERMS if t not in self.physics_terms)

    def restorer(self, stages: Stages) -> LengthRestorer | None:
        """The edge-length stage (built once), or None when ``stages`` or the config skip it."""
        if not (stages.lengths and self.lengths.iterations):
            return None
        if self._restorer is None:
            t, cfg = self.template, self.lengths
            structure = ClothStructure.from_template(t)
            if cfg.edges == "hanging":
                structure = structure.with_edges(
                    hanging_edges(t.vertices, structure.edges, cfg.min_vertical)
                )
            self._restorer = LengthRestorer(structure, cfg)
        return self._restorer

    def onnx_stages(self):
        """The learned stages as ONNX graphs in onnxruntime
        (:class:`~loosefit.inference.onnx_stages.OnnxStages`), exported on first use and
        kept (again when the encoder or generative model has been replaced)."""
        from loosefit.inference.onnx_stages import OnnxStages

        if self._onnx is None or not self._onnx.built_from(self):
            self._onnx = OnnxStages(self)
        return self._onnx

    def animate(
        self,
        motion: Motion,
        progress=None,
        truth=None,
        restart_every=None,
        stages: Stages | None = None,
        runtime: str = "torch",
        collision: str = "full",
    ):
        """:func:`~loosefit.model.rollout.rollout` of ``motion`` (checked first) through the
        motion stage, then the detail stage (if the model has one) and collision handling,
        as ``stages`` (default ``self.stages``) says.

        ``collision``: ``"full"`` (the model's collision handling), or ``"realtime"`` (one
        solve and one round of its last steps a frame, 1.3-2.2x faster:
        :data:`~loosefit.geometry.collision.REALTIME`).

        ``runtime``: what runs the learned stages (the motion stage and the detail
        generator): ``"torch"`` (PyTorch), or ``"onnx"`` (onnxruntime, the graphs exported
        in memory on first use, :mod:`loosefit.inference.onnx_stages`: faster on one core;
        needs ``pip install 'loosefit[onnx]'`` and a model on the CPU). The edge-length
        stage and collision handling are the same Python code either way; the garments
        before collision handling are PyTorch's within float rounding (micrometres).
        """
        check_runtime(runtime)
        self.check_motion(motion)
        stages = stages or self.stages
        with self._collision_as(collision):
            step, detail = self._learned(runtime, stages)
            collide = self.collider(motion) if stages.collision else None
            return rollout(
                self.generative,
                self.encoder,
                motion,
                self.rest_state,
                self.floor_height,
                self.rollout_config,
                progress,
                truth,
                restart_every,
                detail,
                collide,
                stages.feedback,
                stages.overlap,
                self.restorer(stages),
                step,
            )

    def animate_batch(
        self,
        motions: list[Motion],
        progress=None,
        stages: Stages | None = None,
        runtime: str = "torch",
        collision: str = "full",
    ):
        """N motions (N characters) at once: the motion stage batched
        (:func:`~loosefit.model.rollout.rollout_batch`, one network call per frame for all),
        then each motion's detail and collision handling (:func:`~loosefit.model.rollout.
        refine`). The same garments as :meth:`animate` of each, within float rounding;
        ``runtime`` and ``collision`` as for :meth:`animate`.

        Returns:
            One :class:`~loosefit.model.rollout.RolloutResult` per motion.
        """
        check_runtime(runtime)
        for m in motions:
            self.check_motion(m)
        stages = stages or self.stages
        with self._collision_as(collision):
            step, detail = self._learned(runtime, stages)
            results = rollout_batch(
                self.generative,
                self.encoder,
                motions,
                self.rest_state,
                self.floor_height,
                self.rollout_config,
                progress,
                step,
            )
            for m, r in zip(motions, results, strict=True):
                collide = self.collider(m) if stages.collision else None
                refine(
                    r,
                    m,
                    self.floor_height,
                    self.rollout_config,
                    detail,
                    collide,
                    self.device,
                    self.restorer(stages),
                )
        return results

    def _learned(self, runtime: str, stages: Stages) -> tuple:
        """The motion stage's step (None: the networks in PyTorch) and the detail stage
        (None where ``stages`` or the model has none) that ``runtime`` runs them in."""
        detail = self.detail if stages.detail else None
        if runtime != "onnx":
            return None, detail
        return self.onnx_stages().runners(detail, torch.get_num_threads())

    @contextmanager
    def _collision_as(self, collision: str):
        """Within the block, collision handling as the setting ``collision`` says
        (:func:`~loosefit.geometry.collision.collision_setting`): the model's own for
        ``"full"``, its operators kept; otherwise :meth:`configured` with the setting's."""
        setting = collision_setting(self.collision, collision)
        if setting is self.collision:
            yield
        else:
            with self.configured(collision=setting):
                yield

    def carry_drape(self, motion: Motion, progress=None):
        """:func:`~loosefit.model.rollout.carried_drape`: this garment with no dynamics."""
        self.check_motion(motion)
        return carried_drape(motion, self.rest_state, self.floor_height, self.rollout_config)

    def reconstruct(self, motion: Motion, truth: np.ndarray):
        """:func:`~loosefit.model.rollout.reconstruction`: the floor under the encoder's error."""
        self.check_motion(motion)
        return reconstruction(
            self.generative, motion, truth, self.floor_height, self.rollout_config
        )


def load_animation_model(
    path: str | Path, generative: str | Path | None = None, device="cpu"
) -> AnimationModel:
    """The generative and motion stages of a trained model.

    Args:
        path: a motion-stage checkpoint (``checkpoint.pt`` or ``model.pt`` of a run, or a
            packaged ``motion.pt``).
        generative: the generative-stage checkpoint it was trained on; by default
            the one it records (relative to ``path``'s folder, then absolute).
        device: where to put the networks.

    Raises:
        LoosefitInputError: not a motion-stage checkpoint, a missing generative
            checkpoint, or one other than the encoder was trained on.
    """
    path = Path(path)
    data = read_checkpoint_file(path, MOTION_FORMAT, device)
    with checkpoint_fields(path, "motion-stage checkpoint"):
        return _animation_model(path, data, generative, device)


def _animation_model(path: Path, data: dict, generative, device) -> AnimationModel:
    g = data["generative"]
    gpath = recorded_checkpoint(
        path,
        g,
        generative,
        "generative",
        "the generative checkpoint it was trained on",
        "pass --generative FILE",
    )
    gmodel, gdata = load_generative(gpath, device=device)
    found = model_fingerprint(gmodel)
    if found != g["fingerprint"]:
        raise LoosefitInputError(
            gpath,
            "model",
            f"the generative model {path.name} was trained on (fingerprint {g['fingerprint']})",
            f"another one (fingerprint {found})",
        )
    config = model_config(data)
    template = template_from_dict(data["garment"]["template"])
    encoder = DynamicMotionEncoder(
        gmodel, data["num_features"], MotionEncoderConfig(**config["encoder"])
    ).to(device)
    load_weights(encoder, data["model"], path, "this motion encoder's configuration")
    for p in gmodel.parameters():
        p.requires_grad_(False)
    rest = torch.as_tensor(data["rest_state"]).float()
    if rest.shape != (template.num_vertices, 3) or not torch.isfinite(rest).all():
        raise LoosefitInputError(
            path,
            "rest_state",
            f"({template.num_vertices}, 3) finite positions",
            f"shape {tuple(rest.shape)}",
        )
    return AnimationModel(
        gmodel.eval(),
        encoder.eval(),
        template,
        rest.to(device),
        tuple(data["joint_names"]),
        float(data["floor_height"]),
        float(data["fps"]),
        dict(data["body"]),
        RolloutConfig(**config["rollout"]),
        path,
        arm_collision=arm_collision_of(data),
        physics_terms=terms_of(gdata, data),
        trained_on=record if isinstance(record := data.get("trained_on"), dict) else None,
    )


def stage_fingerprints(model: AnimationModel) -> dict:
    """What a detail stage is tied to: the motion stage's weights and the garment."""
    t = model.template
    return {
        "motion": model_fingerprint(model.encoder),
        "garment": garment_fingerprint(t.vertices, t.faces),
    }


def attach_detail(model: AnimationModel, path: str | Path) -> AnimationModel:
    """Load a detail checkpoint into ``model`` (``model.detail``), checked to belong to it.

    Raises:
        LoosefitInputError: not a detail checkpoint, or one trained on another garment or
            another motion stage (the message names both fingerprints).
    """
    path = Path(path)
    data = read_checkpoint_file(path, DETAIL_FORMAT, model.device)
    with checkpoint_fields(path, "detail checkpoint"):
        return _attach(model, path, data)


def _attach(model: AnimationModel, path: Path, data: dict) -> AnimationModel:
    have = stage_fingerprints(model)
    for key, what in (("garment", "garment"), ("motion", "motion stage")):
        if data["fingerprints"][key] != have[key]:
            raise LoosefitInputError(
                path,
                f"fingerprints.{key}",
                f"the {what} of {model.path.name} (fingerprint {have[key]})",
                f"a detail stage trained on another {what} "
                f"(fingerprint {data['fingerprints'][key]})",
            )
    g = DetailGenerator(
        model.template.faces,
        model.template.num_vertices,
        model.encoder.latent,
        DetailConfig(**model_config(data)),
    )
    g = g.to(model.device)
    load_weights(g, data["model"], path, "this detail configuration")
    model.detail = g.eval()
    for prm in g.parameters():
        prm.requires_grad_(False)
    return model


def load_detail_model(
    path: str | Path,
    motion: str | Path | None = None,
    generative: str | Path | None = None,
    device="cpu",
) -> AnimationModel:
    """All three learned stages from a detail checkpoint (and the motion stage it records)."""
    path = Path(path)
    data = read_checkpoint_file(path, DETAIL_FORMAT, "cpu")
    with checkpoint_fields(path, "detail checkpoint"):
        mpath = recorded_checkpoint(
            path,
            data["motion_checkpoint"],
            motion,
            "motion",
            "the motion checkpoint it was trained on",
        )
    model = load_animation_model(mpath, generative, device)
    return attach_detail(model, path)


# -- the baselines ----------------------------------------------------------------------------


@dataclass
class BaselineModel:
    """A trained baseline with the animate() of :class:`AnimationModel`, so that ``loosefit
    animate``/``evaluate`` and the benchmarks run it alike.

    ``stages.collision`` runs Santesteban et al.'s post-process (every vertex closer
    to the body than ``collision.epsilon`` pushed out along the body's normal);
    virtual bones have none (Pan et al. have none). There is no detail stage.
    """

    network: BaselineNetwork
    template: GarmentTemplate
    joint_names: tuple[str, ...]
    floor_height: float
    fps: float
    body: dict
    rollout_config: RolloutConfig
    path: Path
    arm_collision: bool | str = False
    collision: CollisionConfig = field(default_factory=CollisionConfig)
    stages: Stages = field(default_factory=Stages)
    detail: None = None  # no detail stage (what the CLI asks of every model)
    _avatar: object = None

    @property
    def method(self) -> str:
        return self.network.method

    @property
    def device(self) -> torch.device:
        return self.network.rest.device

    @property
    def post_process(self) -> bool:
        """Whether the method has a collision post-process (Santesteban's push-out)."""
        return self.method == "santesteban"

    def avatar(self):
        if self._avatar is None:
            self._avatar = avatar_of(self.body)
        return self._avatar

    def check_motion(self, motion: Motion) -> None:
        check_motion_joints(motion, self.joint_names, self.path)

    def animate(
        self,
        motion: Motion,
        progress=None,
        truth=None,
        restart_every=None,
        stages: Stages | None = None,
        runtime: str = "torch",
        collision: str = "full",
    ):
        """The garment through ``motion`` (T, V, 3) world positions, a
        :class:`~loosefit.model.rollout.RolloutResult`; then the post-process where the
        method has one and ``stages.collision``. ``truth``/``restart_every`` do not
        apply (no previous garment is fed back) and are refused, and so are
        ``runtime="onnx"`` (a baseline runs in PyTorch only) and ``collision="realtime"``
        (its post-process has no rounds to cut)."""
        check_runtime(runtime)
        if collision != "full":
            raise LoosefitInputError(
                self.path,
                "collision",
                f"'full' (the '{self.method}' baseline's own post-process)",
                repr(collision),
            )
        if runtime != "torch":
            raise LoosefitInputError(
                self.path,
                "runtime",
                f"'torch' (a baseline has no ONNX graphs; the '{self.method}' baseline)",
                repr(runtime),
            )
        if restart_every is not None:
            raise LoosefitInputError(
                "BaselineModel.animate",
                "restart_every",
                "None (a baseline never sees the previous garment)",
                restart_every,
            )
        self.check_motion(motion)
        stages = stages or self.stages
        pose = None
        if self.method == "santesteban":
            avatar = self.avatar()
            rot = torch.from_numpy(motion.rotations)
            root = torch.from_numpy(motion.root_translation)

            def pose(s: int, e: int) -> torch.Tensor:
                return avatar.pose(rot[s:e], root[s:e]).joint_transforms

        result = baseline_rollout(
            self.network, motion, self.floor_height, self.rollout_config, pose, progress
        )
        result.stage_seconds = {"motion": result.seconds}
        if stages.collision and self.post_process:
            t0 = time.perf_counter()
            handler = PushOutHandler(
                self.template.faces,
                self.template.num_vertices,
                self.collision.epsilon,
                self.collision.reach,
            )
            arms = True if self.collision.whole_body else self.arm_collision
            collide = body_collider(self.avatar(), handler, motion, arms, self.device)
            result.decoded = result.vertices.copy()
            result.collisions = []
            for t in range(motion.num_frames):
                r = collide(t, torch.from_numpy(result.decoded[t]))
                result.vertices[t] = r.vertices.numpy()
                result.collisions.append(collision_record(r))
            result.stage_seconds["collision"] = time.perf_counter() - t0
            result.seconds += result.stage_seconds["collision"]
        return result


def load_baseline(path: str | Path, device="cpu") -> BaselineModel:
    """A trained baseline from a run's ``model.pt`` or ``checkpoint.pt``.

    Raises:
        LoosefitInputError: not a baseline checkpoint, or weights that do not fit the
            configuration it records.
    """
    path = Path(path)
    data = read_checkpoint_file(
        path,
        BASELINE_FORMAT,
        device,
        {
            MOTION_FORMAT: "this is our motion stage; load it with load_pipeline",
        },
    )
    with checkpoint_fields(path, "baseline checkpoint"):
        return _baseline(path, data, device)


def _baseline(path: Path, data: dict, device) -> BaselineModel:
    config = model_config(data)
    template = template_from_dict(data["garment"]["template"])
    V, K = template.num_vertices, int(data["influences"])
    network = BaselineNetwork(
        BaselineConfig(**config["network"]),
        int(data["num_features"]),
        torch.zeros(V, 3),
        torch.zeros(V, K),
    )
    load_weights(network, data["model"], path, "this baseline's configuration")
    return BaselineModel(
        network.to(device).eval(),
        template,
        tuple(data["joint_names"]),
        float(data["floor_height"]),
        float(data["fps"]),
        dict(data["body"]),
        RolloutConfig(**config["rollout"]),
        path,
        arm_collision=arm_collision_of(data),
    )


# -- any checkpoint ---------------------------------------------------------------------------


def load_pipeline(
    path: str | Path,
    generative: str | Path | None = None,
    detail: str | Path | None = None,
    device="cpu",
):
    """Every learned stage for ``loosefit animate`` / ``evaluate`` from one checkpoint.

    ``path`` is a motion-stage checkpoint (a packaged set's ``motion.pt`` takes the
    ``detail.pt`` beside it, if there is one) or a detail checkpoint (with the motion
    stage it records); ``detail`` names a detail checkpoint explicitly. A baseline's
    checkpoint gives that baseline (:class:`BaselineModel`), which animates alike.

    Returns:
        :class:`AnimationModel` or :class:`BaselineModel`.
    """
    path = Path(path)
    fmt = checkpoint_format(path)
    if fmt == DETAIL_FORMAT:
        return load_detail_model(path, None, generative, device)
    if fmt == BASELINE_FORMAT:
        return load_baseline(path, device)
    model = load_animation_model(path, generative, device)
    beside = path.parent / "detail.pt"
    if detail is None and path.name == "motion.pt" and beside.is_file():
        detail = beside
    return attach_detail(model, detail) if detail is not None else model
