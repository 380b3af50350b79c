"""The Python API: a trained model animating a garment, and the simulator for ground truth.

::

    import loosefit

    model = loosefit.load()                      # the pretrained set (or a checkpoint path)
    result = model.animate("dance:20")           # a .bvh/.npz file, a move, or a Motion
    result.export("dance.usdc")                  # USD; .pc2 (+ OBJ); a folder of OBJs
    result.save("dance.npz")                     # loosefit.AnimatedGarment.load() reads it

Every call checks its inputs and raises :class:`~loosefit.errors.LoosefitInputError`
naming the file or field, what was expected and what was found.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from loosefit import sequence
from loosefit.api.train import TRAINING_STAGES as TRAINING_STAGES
from loosefit.api.train import process_rank as process_rank
from loosefit.api.train import train_baseline as train_baseline
from loosefit.api.train import train_detail as train_detail
from loosefit.api.train import train_engine as train_engine
from loosefit.api.train import train_generative as train_generative
from loosefit.api.train import train_motion as train_motion
from loosefit.api.train import training_config as training_config
from loosefit.errors import LoosefitInputError
from loosefit.inference.protocols import AnimatingModel, BatchAnimatingModel
from loosefit.progress import StageBars as StageBars  # a bar per stage of a long job
from loosefit.progress import tqdm_bar as tqdm_bar  # a bar fed by progress(done, total)
from loosefit.types import GarmentTemplate, Motion

PRETRAINED = "dance"  # the default set's folder under loosefit/pretrained


def check_export_path(path: str | Path) -> None:
    """A clear error, before any work, for an export path no exporter writes
    (:func:`~loosefit.export.check_export_path`; :meth:`AnimatedGarment.export` checks the
    same)."""
    from loosefit.export import check_export_path as check

    check(path)


def is_character(path: str | Path) -> bool:
    """Whether a ``.gltf``/``.glb`` file is a character (a mesh on a skin, which
    :meth:`Animator.dress` dresses), not only a skeleton's animation. False for other
    files."""
    from loosefit.character import has_skinned_mesh

    return has_skinned_mesh(path)


def penetration_tolerance() -> float:
    """How deep (m) cloth inside the body counts as a penetration in the figures of
    collision handling (:data:`~loosefit.garment.quality.PENETRATION_TOLERANCE`)."""
    from loosefit.garment.quality import PENETRATION_TOLERANCE

    return PENETRATION_TOLERANCE


def show(
    *sequences: sequence.GarmentSequence,
    names: list[str] | None = None,
    wait: bool = True,
    **config,
):
    """Open animated garments in the browser viewer (:mod:`loosefit.view`;
    ``pip install 'loosefit[viewer]'``): one, or several of the same garment and frames
    side by side. Any :class:`~loosefit.sequence.GarmentSequence` will do: a rollout, a
    file read with ``AnimatedGarment.load``, a data set's clip
    (``DatasetReader(folder).read(name)``).

    Prints the URL; with ``wait`` serves until Ctrl-C, otherwise returns the running
    :class:`~loosefit.view.server.Viewer` at once (``close()`` it). ``config``:
    :class:`~loosefit.view.ViewerConfig` fields, e.g. ``port=8081``,
    ``colouring="error"``, ``layout="overlaid"``.
    """
    from loosefit.view import ViewerConfig, view

    viewer = view(list(sequences), names, ViewerConfig(**config))
    print(f"loosefit viewer: {viewer.url}", flush=True)
    if wait:
        viewer.wait()
    return viewer


class AnimatedGarment(sequence.GarmentSequence):
    """An animated garment as the API returns it (``loosefit.AnimatedGarment``): the
    sequence of :mod:`loosefit.sequence` (its fields, file, export) and :meth:`view`, the
    browser viewer, which sits in a layer above the sequence's and is reached from here
    (:func:`show` opens any sequence). :meth:`load` reads a file as one of these.

    ``rollout``: made by :meth:`Animator.animate`, the rollout's figures
    (:class:`~loosefit.inference.rollout.RolloutResult`: seconds, frames computed, collision
    handling per frame); None otherwise."""

    rollout = None  # the RolloutResult of Animator.animate (None: read, simulated)

    def view(
        self,
        *others: sequence.GarmentSequence,
        names: list[str] | None = None,
        wait: bool = True,
        **config,
    ):
        """Open this sequence (and ``others`` of the same garment and frames, side by side)
        in the browser viewer: :func:`show` with this one first."""
        return show(self, *others, names=names, wait=wait, **config)


def pretrained_checkpoint() -> Path:
    """The pretrained set's motion stage, shipped inside the package (``loosefit/pretrained/
    dance``, trained on the simulated ``dance`` corpus: salsa, ballet and modern dance;
    ``checkpoints/dance`` in a checkout)."""
    from importlib.resources import files

    return Path(str(files("loosefit") / "pretrained" / PRETRAINED / "motion.pt"))


def trained_on(path: str | Path) -> str:
    """What a checkpoint's model was trained on, in words (see :attr:`Animator.trained_on`)."""
    from loosefit.inference.checkpoints import load_torch
    from loosefit.inference.package import describe_training

    data = load_torch(Path(path))
    return describe_training(data.get("trained_on") if isinstance(data, dict) else None)


def motion_for(
    spec: str | Path | Motion,
    avatar,
    fps: float,
    frames: int | None = None,
    start_frame: int = 0,
    seed: int = 0,
    *,
    retarget=None,
    max_frames: int | None = None,
) -> Motion:
    """A motion on the avatar's skeleton at ``fps``, ``frames`` long (played again if longer).

    Args:
        spec: a :class:`~loosefit.types.Motion`, or what
            :func:`~loosefit.motion.motions.load_motion` reads (a ``.bvh``/``.npz`` file, a
            procedural move, ``dance:SECONDS``, ``mirror:...``, ``A+B``).
        avatar: the avatar it must fit.
        fps: the frame rate the model runs at.
        frames: frames to keep (more than the motion has: it plays again); None: all.
        start_frame: drop the frames before this one.
        seed: seeds procedural motions.
        retarget: how a BVH file is read and mapped
            (:class:`~loosefit.motion.retarget.RetargetConfig`; default: its defaults).
        max_frames: keep at most this many of the motion's frames (before ``frames``).
    """
    from loosefit.motion.chain import chain_motions
    from loosefit.motion.motions import load_motion

    if isinstance(spec, Motion):
        avatar.check_motion(spec)
        if abs(spec.fps - fps) > 1e-6:
            raise LoosefitInputError(
                f"motion '{spec.name}'",
                "fps",
                f"{fps:g} (the model's)",
                f"{spec.fps:g}",
                hint="resample it",
            )
        motion = spec.slice(start_frame, spec.num_frames)
        if max_frames is not None:
            motion = motion.slice(0, min(max_frames, motion.num_frames))
    else:
        motion = load_motion(
            spec,
            avatar,
            fps=fps,
            seed=seed,
            retarget=retarget,
            max_frames=max_frames,
            start_frame=start_frame,
        )
    if frames is not None:
        if frames < 1:
            raise LoosefitInputError("frames", "frames", "at least 1", frames)
        if frames > motion.num_frames:  # play it again, from where it ended
            motion = chain_motions([motion] * -(-frames // motion.num_frames), name=motion.name)
        motion = motion.slice(0, frames)
    return motion


class Animator:
    """A trained model (ours, or a baseline) ready to animate its garment.

    Attributes:
        model: the loaded stages, an :class:`~loosefit.inference.protocols.AnimatingModel`
            (:class:`~loosefit.inference.animator.AnimationModel` or a
            :class:`~loosefit.inference.baseline.BaselineModel`).
        path: the checkpoint it came from.
    """

    def __init__(self, model: AnimatingModel, path: Path) -> None:
        self.model, self.path = model, Path(path)

    @property
    def template(self) -> GarmentTemplate:
        """The garment the model animates."""
        return self.model.template

    @property
    def fps(self) -> float:
        return float(self.model.fps)

    @property
    def trained_on(self) -> str:
        """What the model was trained on, in words (a packaged set records it), e.g. "the
        `dance` data set (16 clips, 5,656 frames, and their mirror images), fine-tuned from
        the `salsa` set"."""
        from loosefit.inference.package import describe_training

        return describe_training(getattr(self.model, "trained_on", None))

    def animate(
        self,
        motion: str | Path | Motion,
        frames: int | None = None,
        start_frame: int = 0,
        seed: int = 0,
        stages=None,
        progress: Callable[[int, int], None] | None = None,
        *,
        runtime: str = "torch",
        collision: str = "full",
        threads: int | None = None,
        shape: dict | None = None,
        retarget=None,
        realisation: int | None = None,
    ) -> AnimatedGarment:
        """The garment through a motion.

        Args:
            motion: a file, a procedural move or a :class:`~loosefit.types.Motion`
                (see :func:`motion_for`).
            frames: how many frames (None: the motion's).
            start_frame: the motion's first frame to use.
            seed: seeds procedural motions.
            stages: which stages run after the decoders
                (:class:`~loosefit.inference.stages.Stages`; default all).
            progress: called as ``progress(done, total)``.
            runtime: what runs the learned stages: ``"torch"`` (PyTorch), or ``"onnx"``
                (onnxruntime: the same garments, faster on one core; ``pip install
                'loosefit[onnx]'``; docs/use/ENGINE_EXPORT.md). Edge lengths and collision
                handling are the same Python code either way.
            collision: ``"full"`` (default), or ``"realtime"``: one solve and one round of
                the last projection and of the mending a frame, 1.3-2.2x faster collision
                handling, a little more cloth left within a millimetre of the skin
                (docs/results/BENCHMARKS.md, "Collision handling: full and realtime").
            threads: torch's intra-op threads for this call (an int >= 1); None: the free
                cores, at most 4 (:func:`~loosefit.inference.threads.default_threads`:
                fewer on a busy machine, torch's own count kept where ``OMP_NUM_THREADS``
                is set). Torch's count before the call comes back after it
                (docs/use/THREADS.md).
            shape: another body, as anny phenotypes (``{"height": 0.8, "weight": 0.3}``,
                names among gender, age, muscle, weight, height, proportions, each in
                [0, 1]; those not named as the trained body's). The garment is sized to
                that body and animated on it (:mod:`loosefit.inference.other_body`;
                prepared once per body, a few seconds). None: the trained body.
            retarget: how a BVH file is read and mapped (see :func:`motion_for`).
            realisation: None, the motion stage's garment (the centre of what the cloth may
                do); an int >= 0, that realisation of the set's residual process
                (:mod:`loosefit.model.residual`): the cloth as one more simulation from
                another start might land, the same garments on every run and machine.

        Returns:
            :class:`AnimatedGarment`, world positions; its ``rollout`` the rollout's
            figures.

        Raises:
            LoosefitInputError: an unreadable motion, ``runtime="onnx"`` without
                onnxruntime or for a baseline, ``threads`` not an int >= 1, a
                ``shape`` with a name anny does not have or a value outside [0, 1], or a
                ``realisation`` of a model with no residual process.
        """
        from loosefit.inference.threads import inference_threads

        with inference_threads(threads):
            body = self.other_body(shape)
            avatar = body.avatar if body is not None else self.model.avatar()
            m = motion_for(motion, avatar, self.fps, frames, start_frame, seed, retarget=retarget)
            kwargs = {"body": body} if body is not None else {}
            if realisation is not None:
                if not hasattr(self.model, "residual_offsets"):
                    raise LoosefitInputError(
                        self.path,
                        "realisation",
                        "a model of the paper's stages with a residual process",
                        f"{type(self.model).__name__} (it has no realisations)",
                    )
                kwargs["realisation"] = realisation
            result = self.model.animate(
                m, progress, stages=stages, runtime=runtime, collision=collision, **kwargs
            )
        template = body.template if body is not None else self.template
        record = {"rig": avatar.config.rig, "shape": dict(avatar.shape)}
        out = AnimatedGarment(m, template, result.vertices, record, f"loosefit model {self.path}")
        out.rollout = result
        return out

    def avatar(self, shape: dict | None = None):
        """The body a motion is animated on: the trained body's avatar, or ``shape``'s
        (:meth:`other_body`)."""
        body = self.other_body(shape)
        return body.avatar if body is not None else self.model.avatar()

    def dress(
        self,
        character: str | Path,
        frames: int | None = None,
        progress: Callable[[int, int], None] | None = None,
        threads: int | None = None,
        *,
        retarget=None,
    ):
        """The garment on a user's own character: a skinned, animated ``.glb``/``.gltf``
        (Mixamo, Blender, Unity or Unreal export). anny's body is fitted to the
        character's skin, the garment animated on it, carried onto the character's own mesh
        and kept out of it (:mod:`loosefit.character`). ``retarget``: how its animation is
        read and mapped (:class:`~loosefit.motion.retarget.RetargetConfig`).

        Returns:
            :class:`~loosefit.character.dress.DressedCharacter`: ``vertices`` in the
            character's world; ``export("out.glb")`` writes their file with the garment,
            ``export("garment.usd")`` (``.abc``, ``.pc2``) the garment alone beside it.

        Raises:
            LoosefitInputError: a file with no mesh, skin or animation; a character anny
                cannot fit (the misfit measured, and what would help); a baseline.
        """
        from loosefit.character import dress_character
        from loosefit.inference.threads import inference_threads

        with inference_threads(threads):
            return dress_character(self.model, character, frames, progress, retarget=retarget)

    def other_body(self, shape: dict | None):
        """The body of ``shape`` (:meth:`animate`), prepared once and kept; None for None,
        ``{}`` or the trained body's own values.

        Raises:
            LoosefitInputError: a model that cannot change body (a baseline), a phenotype
                name anny does not have, or a value outside [0, 1].
        """
        if not shape:
            return None
        trained = getattr(self.model, "body", {}).get("shape", {})
        if all(k in trained and shape[k] == trained[k] for k in shape):  # the trained body
            return None
        if not hasattr(self.model, "other_body"):
            raise LoosefitInputError(
                self.path,
                "shape",
                "our model (a baseline animates on the body it was trained on)",
                type(self.model).__name__,
            )
        return self.model.other_body(shape)

    def animate_batch(
        self,
        motions: list,
        frames: int | None = None,
        seed: int = 0,
        stages=None,
        progress=None,
        *,
        runtime: str = "torch",
        collision: str = "full",
        threads: int | None = None,
        shape: dict | None = None,
    ) -> list[AnimatedGarment]:
        """N motions (files, moves or :class:`~loosefit.types.Motion`) at once, N characters:
        the motion stage runs batched (one network call per frame for all of them). ``seed``
        seeds procedural motions (the i-th gets ``seed + i``); ``runtime``, ``collision``,
        ``threads`` and ``shape`` (every character on that body) as for :meth:`animate`.

        Returns:
            One :class:`~loosefit.sequence.GarmentSequence` per motion.

        Raises:
            LoosefitInputError: a motion on other joints, at another rate, or unreadable;
                ``threads`` not an int >= 1.
        """
        from loosefit.inference.threads import inference_threads

        if not isinstance(self.model, BatchAnimatingModel):
            raise LoosefitInputError(
                self.path,
                "model",
                "our model (a baseline animates one motion at a time)",
                type(self.model).__name__,
            )
        with inference_threads(threads):
            body = self.other_body(shape)
            avatar = body.avatar if body is not None else self.model.avatar()
            ms = [
                motion_for(m, avatar, self.fps, frames, 0, seed + i) for i, m in enumerate(motions)
            ]
            kwargs = {"body": body} if body is not None else {}
            results = self.model.animate_batch(
                ms, progress, stages=stages, runtime=runtime, collision=collision, **kwargs
            )
        template = body.template if body is not None else self.template
        record = {"rig": avatar.config.rig, "shape": dict(avatar.shape)}
        return [
            AnimatedGarment(m, template, r.vertices, record, f"loosefit model {self.path}")
            for m, r in zip(ms, results, strict=True)
        ]

    def export_onnx(self, path: str | Path, detail: bool = True, check: bool = True) -> list[Path]:
        """The learned runtime (motion features, the motion encoder's step, the decoders, the
        detail generator) as one ONNX graph at ``path``, its GRU state and previous garment
        explicit inputs and outputs, a JSON beside it saying what they mean and the
        garment's mesh as OBJ (:func:`~loosefit.inference.onnx.export.export_onnx`;
        docs/use/ENGINE_EXPORT.md).

        Args:
            path: the ``.onnx`` file.
            detail: the detail stage in the graph (when the model has one).
            check: one frame through onnxruntime against PyTorch before keeping the file.

        Returns:
            The ``.onnx``, ``.json`` and ``.obj`` paths.

        Raises:
            LoosefitInputError: a stage that cannot be exported (a baseline), or the
                ``onnx`` extra missing (``pip install 'loosefit[onnx]'``).
        """
        from loosefit.inference.onnx.export import OnnxExportConfig, export_onnx

        return export_onnx(self.model, path, OnnxExportConfig(detail=detail, check=check))


def load(
    path: str | Path | None = None,
    device: str = "cpu",
    *,
    generative: str | Path | None = None,
    detail: str | Path | None = None,
) -> Animator:
    """A trained model: the pretrained set by default, or any checkpoint the project writes
    (:data:`~loosefit.inference.loader.CHECKPOINTS`): a set's folder or its
    ``motion.pt``, ``generative.pt`` or ``engine.pt``; a run's ``model.pt`` or
    ``checkpoint.pt`` of the motion, detail, baseline or engine stage; a packaged set. Each
    file is read once. ``generative``: the generative checkpoint a motion or detail stage
    was trained on, if not the one it records; ``detail``: a detail checkpoint to attach.

    Raises:
        LoosefitInputError: a missing or unreadable checkpoint, or one of a format that does
            not animate (naming the file, the format found and the formats accepted).
    """
    from loosefit.inference.loader import load_model

    path = Path(path) if path is not None else pretrained_checkpoint()
    if not path.exists():
        raise LoosefitInputError(path, "checkpoint", "a trained model's checkpoint", "no such file")
    return Animator(load_model(path, device, generative=generative, detail=detail), path)


def package(
    checkpoint: str | Path,
    out: str | Path,
    *,
    generative: str | Path | None = None,
    detail: str | Path | None = None,
) -> list[Path]:
    """A trained model as one folder to share (:mod:`loosefit.inference.package`):
    ``generative.pt`` and ``motion.pt`` of a motion run's ``checkpoint`` (``generative``: its
    generative checkpoint, if not the one it records), and ``detail.pt`` of a detail run's
    ``detail`` checkpoint; half-precision weights, each stage pointing at the one before.

    Returns:
        The files written.

    Raises:
        LoosefitInputError: stages that do not belong together, or not such checkpoints.
    """
    from loosefit.inference.package import package_detail, package_model

    files = list(package_model(checkpoint, out, generative))
    if detail:
        files.append(package_detail(detail, out))
    return files


def simulate(
    motion: str | Path | Motion,
    garment: str | GarmentTemplate = "flared",
    frames: int | None = None,
    start_frame: int = 0,
    seed: int = 0,
    config=None,
    *,
    shape: dict | None = None,
    progress=None,
    unfold: bool = True,
) -> AnimatedGarment:
    """Ground truth: the garment simulated on the avatar (Newton VBD; minutes per second of
    motion on a CPU).

    Args:
        motion: as for :meth:`Animator.animate` (at 30 fps).
        garment: a skirt style (``aline``, ``flared``, ``circle``), ``dress`` or
            ``dress-strapless``, a garment file (``.obj``, ``.gltf``, ``.glb``: imported
            onto the avatar), or a :class:`~loosefit.types.GarmentTemplate` on its rest pose.
        frames, start_frame, seed: as for :meth:`Animator.animate`.
        config: the physics (:class:`~loosefit.sim.cloth_config.ClothConfig`; default settings,
            the upper arms in the collider for a dress).
        shape: the avatar's phenotype (anny's names); default the project's avatar.
        progress: called as ``progress(done, total)``.
        unfold: first turn a limb that passes into the body out of it, a few degrees at most,
            as data sets do (:mod:`loosefit.motion.pose_correction`; the returned motion is the one
            simulated); False simulates the motion exactly as given.
    """
    from loosefit.body.avatar import Avatar, AvatarConfig
    from loosefit.fitting.place import garment_for
    from loosefit.sim.driver import simulate as run

    avatar = Avatar(AvatarConfig(shape=dict(shape or {})) if shape else None)
    template = garment if isinstance(garment, GarmentTemplate) else garment_for(garment, avatar)
    if isinstance(garment, GarmentTemplate):  # one fitted to a body (fit_garment): that body
        from loosefit.fitting.place import check_fitted_shape

        check_fitted_shape(template, avatar, "garment")
    m = motion_for(motion, avatar, 30.0, frames, start_frame, seed)
    if config is None:  # a dress's bodice reaches the upper arms: they collide
        from loosefit.fitting.place import collider_arms
        from loosefit.sim.cloth_config import ClothConfig

        config = ClothConfig(arm_collision=collider_arms(template))
    if unfold:
        from loosefit.body.regions import body_parts
        from loosefit.motion.pose_correction import unfold_motion

        m = unfold_motion(avatar, m, body_parts(avatar, arms=config.colliding_arms)).motion
    result = run(avatar, template, m, config, progress=progress)
    from loosefit.api.garment import dressed_sequence

    return dressed_sequence(m, template, result.garment_vertices, avatar, "newton-vbd")
