"""The paper's trained model that animates a garment, loaded from its checkpoints.

:class:`AnimationModel` (paper 3.2-3.5, :meth:`AnimationModel.from_checkpoint`) is one
:class:`~loosefit.inference.protocols.AnimatingModel`; any checkpoint is opened through the
table of formats (:func:`~loosefit.inference.loader.load_model`, what
:func:`loosefit.load` wraps).
Models are rebuilt from the checkpoints' ``model_config``
(:mod:`loosefit.inference.checkpoints`); nothing here reads a training configuration.
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from loosefit.errors import LoosefitInputError
from loosefit.inference.checkpoints import (
    DETAIL_FORMAT,
    MOTION_FORMAT,
    check_fingerprints,
    checkpoint_fields,
    load_generative,
    load_weights,
    model_config,
    model_fingerprint,
    read_checkpoint_file,
    read_file,
    recorded_checkpoint,
    template_from_dict,
)
from loosefit.inference.model_common import (
    arm_collision_of,
    avatar_of,
    body_collider,
    check_motion_joints,
    check_runtime,
)
from loosefit.inference.other_body import BodyCarryStage, OtherBody
from loosefit.inference.references import carried_drape, reconstruction
from loosefit.inference.residual import attach_residual
from loosefit.inference.rollout import (
    MotionStage,
    RestartFromTruth,
    RolloutHooks,
    RolloutOptions,
    RolloutResult,
    StepFunction,
    refine,
    rollout,
    rollout_batch,
)
from loosefit.inference.stages import Stage, Stages
from loosefit.inference.stages.collision import (
    BodyCollider,
    CollisionConfig,
    CollisionHandler,
    CollisionStage,
    collision_setting,
)
from loosefit.inference.stages.detail import DetailNetwork, DetailStage
from loosefit.inference.stages.lengths import (
    LengthConfig,
    LengthRestorer,
    LengthStage,
    length_restorer,
)
from loosefit.inference.timeline import RolloutConfig
from loosefit.model.detail import DetailConfig, DetailGenerator
from loosefit.model.generative import GarmentGenerativeModel
from loosefit.model.losses import PHYSICS_TERMS, terms_of
from loosefit.model.motion_encoder import DynamicMotionEncoder, MotionEncoderConfig
from loosefit.model.residual import ResidualProcess, motion_intensity, residual_offsets
from loosefit.types import GarmentTemplate, Motion

# -- the paper's model ------------------------------------------------------------------------


@dataclass(kw_only=True)
class AnimationModel:
    """The paper's stages (3.2-3.5), everything a rollout needs: built by keyword, or from a
    checkpoint (:meth:`from_checkpoint`).

    A frame goes through :meth:`animate`: the motion stage (:meth:`motion_stage`, the
    encoder and the decoders), then :meth:`later_stages` (detail, edge lengths, collision),
    run by :func:`~loosefit.inference.rollout.rollout`.
    """

    generative: GarmentGenerativeModel  # the generative stage (its decoders)
    encoder: DynamicMotionEncoder  # the motion stage
    template: GarmentTemplate  # the garment it animates (V vertices)
    rest_state: torch.Tensor  # (V, 3) the settled drape in the rest pose's root frame
    joint_names: tuple[str, ...]  # the skeleton a motion must be on
    floor_height: float  # the avatar's standing root height
    fps: float  # the frame rate it was trained at
    body: dict  # the avatar's record (its shape)
    rollout_config: RolloutConfig  # the timeline before a motion's first frame
    path: Path  # the checkpoint it came from
    detail: torch.nn.Module | None = None  # paper 3.4 (a DetailGenerator), if trained
    collision: CollisionConfig = field(default_factory=CollisionConfig)  # paper 3.5
    arm_collision: bool | str = False  # the arms in the collider, as the data's simulation
    stages: Stages = field(default_factory=Stages)  # what animate() runs by default
    lengths: LengthConfig = field(default_factory=LengthConfig)  # edges back to rest length
    physics_terms: tuple[str, ...] = ()  # the physics terms the stages were trained with
    trained_on: dict | None = None  # a packaged set's training record (package.training_record)
    residual: ResidualProcess | None = None  # its realisations (residual.pt), if fitted
    _avatar: object = None  # the avatar, built on first use
    _handler: CollisionHandler | None = None  # Eq. 16's operators, built on first use
    _restorer: LengthRestorer | None = None  # the edge-length operator, built on first use
    _onnx: object = None  # the learned stages in onnxruntime (OnnxStages), built once
    _bodies: dict = field(default_factory=dict)  # other bodies (OtherBody) by their shape

    @classmethod
    def from_checkpoint(
        cls,
        path: str | Path,
        generative: str | Path | None = None,
        detail: str | Path | None = None,
        device="cpu",
        data: dict | None = None,
    ) -> AnimationModel:
        """Every learned stage of the paper's model from one checkpoint.

        Args:
            path: a motion-stage checkpoint (``checkpoint.pt`` or ``model.pt`` of a run, or
                a packaged ``motion.pt``, which takes the ``detail.pt`` and ``residual.pt``
                beside it, if there are), or a detail checkpoint (with the motion stage it
                records).
            generative: the generative-stage checkpoint; by default the one recorded.
            detail: a detail checkpoint to attach explicitly.
            device: where to put the networks.
            data: ``path``'s contents, when already read (each file is read once).

        Raises:
            LoosefitInputError: not such a checkpoint, or stages that do not belong together.
        """
        path = Path(path)
        data = read_file(path, device) if data is None else data
        if isinstance(data, dict) and data.get("format") == DETAIL_FORMAT:
            return load_detail_model(path, None, generative, device, data=data)
        model = load_animation_model(path, generative, device, data=data)
        beside = path.parent / "detail.pt"
        if detail is None and path.name == "motion.pt" and beside.is_file():
            detail = beside
        if path.name == "motion.pt" and (path.parent / "residual.pt").is_file():
            attach_residual(model, path.parent / "residual.pt")
        return attach_detail(model, detail) if detail is not None else model

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
            self._restorer = length_restorer(self.template, self.lengths)
        return self._restorer

    def onnx_stages(self):
        """The learned stages as ONNX graphs in onnxruntime
        (:class:`~loosefit.inference.onnx.stages.OnnxStages`), exported on first use and
        kept (again when the encoder or generative model has been replaced)."""
        from loosefit.inference.onnx.stages import OnnxStages

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
        *,
        collision: str = "full",
        body: OtherBody | None = None,
        realisation: int | None = None,
    ) -> RolloutResult:
        """:func:`~loosefit.inference.rollout.rollout` of ``motion`` (checked first) through
        the motion stage, then the detail stage (if the model has one), the edge lengths
        and collision handling, as ``stages`` (default ``self.stages``) says.

        ``truth`` (T, V, 3) and ``restart_every``: a drift measurement
        (:class:`~loosefit.inference.rollout.RestartFromTruth`).

        ``collision``: ``"full"`` (the model's collision handling), or ``"realtime"`` (one
        solve and one round of its last steps a frame, 1.3-2.2x faster:
        :data:`~loosefit.inference.stages.collision.REALTIME`).

        ``runtime``: what runs the learned stages (the motion stage and the detail
        generator): ``"torch"`` (PyTorch), or ``"onnx"`` (onnxruntime, the graphs exported
        in memory on first use, :mod:`loosefit.inference.onnx.stages`: faster on one core;
        needs ``pip install 'loosefit[onnx]'`` and a model on the CPU). The edge-length
        stage and collision handling are the same Python code either way; the garments
        before collision handling are PyTorch's within float rounding (micrometres).

        ``body``: another body (:meth:`other_body`), ``motion`` on it; the motion stage runs
        on the trained body and the garment is carried onto this one, then fitted to it
        (:mod:`loosefit.inference.other_body`).

        ``realisation``: None, the motion stage's garment (the centre of what the cloth may
        do); an int >= 0, that realisation of the model's residual process
        (:mod:`loosefit.model.residual`), the same on every run and machine.

        Raises:
            LoosefitInputError: a ``realisation`` asked of a model with no residual process,
                or one that is not an int >= 0.
        """
        check_runtime(runtime)
        self.check_motion(motion)
        stages = stages or self.stages
        run_motion = self._trained_motion(motion, body, stages)
        hooks = RolloutHooks(progress=progress)
        if realisation is not None:
            hooks.offsets = self.residual_offsets(motion, realisation)
        if restart_every is not None:
            shape = (motion.num_frames, self.template.num_vertices, 3)
            hooks.restart = RestartFromTruth(truth, restart_every, shape, self.device)
        with self._collision_as(collision):
            step, detail = self._learned(runtime, stages)
            later = self.later_stages(motion, stages, detail, body)
            options = RolloutOptions(later, feedback=stages.feedback, overlap=stages.overlap)
            result = rollout(self.motion_stage(step), run_motion, options, hooks)
        result.collisions = collision_records(later)
        return result

    def other_body(self, shape: dict) -> OtherBody:
        """Another anny body for :meth:`animate` (``shape``: phenotype names to values in
        [0, 1], the rest as the trained body's), prepared once per shape and kept."""
        key = tuple(sorted((str(k), float(v)) for k, v in shape.items()))
        if key not in self._bodies:
            self._bodies[key] = OtherBody.prepare(dict(shape), self.avatar(), self.template)
        return self._bodies[key]

    def _trained_motion(self, motion: Motion, body: OtherBody | None, stages: Stages) -> Motion:
        """The motion the motion stage runs: ``motion`` itself, or on another body's
        behalf, the same motion on the trained body."""
        if body is None:
            return motion
        if stages.feedback:
            raise LoosefitInputError(
                "stages",
                "feedback",
                "False on another body (the motion stage runs on the trained body)",
                True,
            )
        body.avatar.check_motion(motion)
        return body.trained_motion(motion)

    def animate_batch(
        self,
        motions: list[Motion],
        progress=None,
        stages: Stages | None = None,
        runtime: str = "torch",
        collision: str = "full",
        body: OtherBody | None = None,
    ) -> list[RolloutResult]:
        """N motions (N characters) at once: the motion stage batched
        (:func:`~loosefit.inference.rollout.rollout_batch`, one network call per frame for
        all), then each motion's later stages (:func:`~loosefit.inference.rollout.refine`).
        The same garments as :meth:`animate` of each, within float rounding; ``runtime`` and
        ``collision`` and ``body`` (every motion on it) as for :meth:`animate`.

        Returns:
            One :class:`~loosefit.inference.rollout.RolloutResult` per motion.
        """
        check_runtime(runtime)
        for m in motions:
            self.check_motion(m)
        stages = stages or self.stages
        runs = [self._trained_motion(m, body, stages) for m in motions]
        with self._collision_as(collision):
            step, detail = self._learned(runtime, stages)
            motion_stage = self.motion_stage(step)
            results = rollout_batch(motion_stage, runs, progress)
            for m, run, r in zip(motions, runs, results, strict=True):
                later = self.later_stages(m, stages, detail, body)
                refine(r, run, motion_stage, later)
                if later:
                    r.collisions = collision_records(later)
        return results

    def residual_offsets(self, motion: Motion, realisation: int) -> torch.Tensor:
        """(T, V, 3) realisation ``realisation``'s root-frame offsets along ``motion``
        (:func:`~loosefit.model.residual.residual_offsets`, its spread following the
        motion's intensity)."""
        if self.residual is None:
            raise LoosefitInputError(
                self.path,
                "residual.pt",
                "a set with a residual process, for a realisation",
                "none beside this motion stage",
                hint="fit one: loosefit train residual --motion MOTION.pt --data DATA",
            )
        intensity = motion_intensity(motion.rotations, motion.fps)
        return residual_offsets(self.residual, motion.num_frames, realisation, intensity)

    def motion_stage(self, step: StepFunction | None = None) -> MotionStage:
        """The motion stage a rollout runs (``step``: its network call, e.g. in
        onnxruntime; None: the encoder and the decoders in PyTorch)."""
        return MotionStage(
            self.generative,
            self.encoder,
            self.rest_state,
            self.floor_height,
            self.rollout_config,
            step,
        )

    def later_stages(
        self,
        motion: Motion,
        stages: Stages,
        detail: DetailNetwork | None,
        body: OtherBody | None = None,
    ) -> list[Stage]:
        """The stages after the motion stage that ``stages`` asks, in order, for ``motion``:
        ``detail`` (the detail network to run, or None), the carry onto ``body`` (another
        body, ``motion`` on it), the edge lengths, collision (against ``body``)."""
        later: list[Stage] = []
        if detail is not None:
            later.append(DetailStage(detail, self.device))
        if body is not None:
            later.append(BodyCarryStage(body, body.trained_motion(motion), motion))
            return later + self._body_stages(motion, stages, body)
        restorer = self.restorer(stages)
        if restorer is not None:
            later.append(LengthStage(restorer))
        if stages.collision:
            later.append(CollisionStage(self.collider(motion), self.device))
        return later

    def _body_stages(self, motion: Motion, stages: Stages, body: OtherBody) -> list[Stage]:
        """The edge lengths and collision handling on another body: its garment's rest
        lengths, its skin (each built once per body and kept on it)."""
        later: list[Stage] = []
        if stages.lengths and self.lengths.iterations:
            if body.restorer is None:
                body.restorer = length_restorer(body.template, self.lengths)
            later.append(LengthStage(body.restorer))
        if stages.collision:
            if body.handler is None:
                t = body.template
                rest = np.asarray(t.vertices, np.float64)
                body.handler = CollisionHandler(t.faces, t.num_vertices, self.collision, rest)
            arms = True if self.collision.whole_body else self.arm_collision
            collide = body_collider(body.avatar, body.handler, motion, arms, self.device)
            later.append(CollisionStage(collide, self.device))
        return later

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
        (:func:`~loosefit.inference.stages.collision.collision_setting`): the model's own for
        ``"full"``, its operators kept; otherwise :meth:`configured` with the setting's."""
        setting = collision_setting(self.collision, collision)
        if setting is self.collision:
            yield
        else:
            with self.configured(collision=setting):
                yield

    def carry_drape(self, motion: Motion, progress=None):
        """:func:`~loosefit.inference.references.carried_drape`: this garment with no dynamics."""
        self.check_motion(motion)
        return carried_drape(motion, self.rest_state, self.floor_height, self.rollout_config)

    def reconstruct(self, motion: Motion, truth: np.ndarray):
        """:func:`~loosefit.inference.references.reconstruction`: the floor under the
        encoder's error."""
        self.check_motion(motion)
        return reconstruction(
            self.generative, motion, truth, self.floor_height, self.rollout_config
        )


def load_animation_model(
    path: str | Path, generative: str | Path | None = None, device="cpu", data: dict | None = None
) -> AnimationModel:
    """The generative and motion stages of a trained model.

    Args:
        path: a motion-stage checkpoint (``checkpoint.pt`` or ``model.pt`` of a run, or a
            packaged ``motion.pt``).
        generative: the generative-stage checkpoint it was trained on; by default
            the one it records (relative to ``path``'s folder, then absolute).
        device: where to put the networks.
        data: ``path``'s contents, when already read.

    Raises:
        LoosefitInputError: not a motion-stage checkpoint, a missing generative
            checkpoint, or one other than the encoder was trained on.
    """
    path = Path(path)
    data = read_checkpoint_file(path, MOTION_FORMAT, device, data=data)
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
        generative=gmodel.eval(),
        encoder=encoder.eval(),
        template=template,
        rest_state=rest.to(device),
        joint_names=tuple(data["joint_names"]),
        floor_height=float(data["floor_height"]),
        fps=float(data["fps"]),
        body=dict(data["body"]),
        rollout_config=RolloutConfig(**config["rollout"]),
        path=path,
        arm_collision=arm_collision_of(data),
        physics_terms=terms_of(gdata, data),
        trained_on=record if isinstance(record := data.get("trained_on"), dict) else None,
    )


def attach_detail(
    model: AnimationModel, path: str | Path, data: dict | None = None
) -> AnimationModel:
    """Load a detail checkpoint into ``model`` (``model.detail``), checked to belong to it
    (``data``: the file's contents, when already read).

    Raises:
        LoosefitInputError: not a detail checkpoint, or one trained on another garment or
            another motion stage (the message names both fingerprints).
    """
    path = Path(path)
    data = read_checkpoint_file(path, DETAIL_FORMAT, model.device, data=data)
    with checkpoint_fields(path, "detail checkpoint"):
        return _attach(model, path, data)


def _attach(model: AnimationModel, path: Path, data: dict) -> AnimationModel:
    check_fingerprints(model, path, data, "a detail stage trained on")
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
    data: dict | None = None,
) -> AnimationModel:
    """All three learned stages from a detail checkpoint (and the motion stage it records;
    ``data``: the detail file's contents, when already read)."""
    path = Path(path)
    data = read_checkpoint_file(path, DETAIL_FORMAT, "cpu", data=data)
    with checkpoint_fields(path, "detail checkpoint"):
        mpath = recorded_checkpoint(
            path,
            data["motion_checkpoint"],
            motion,
            "motion",
            "the motion checkpoint it was trained on",
        )
    model = load_animation_model(mpath, generative, device)
    return attach_detail(model, path, data)


# -- any checkpoint ---------------------------------------------------------------------------


def collision_records(stages: list[Stage]) -> list[dict] | None:
    """The collision stage's figures per motion frame, or None when none of ``stages`` is
    the collision stage."""
    for stage in stages:
        if isinstance(stage, CollisionStage):
            return stage.records
    return None
