"""Exports through the API: a sequence to USD, Alembic, glTF, PC2 or OBJ files
(:mod:`loosefit.export`), and a trained model's runtime as ONNX for a game engine, the full
learned runtime (:mod:`loosefit.inference.onnx.export`) or the engine tier
(:mod:`loosefit.inference.engine.export`); docs/use/ENGINE_EXPORT.md. Each imports what it
needs when called."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from loosefit.errors import LoosefitInputError

# the configurations the exports take, imported on first use (they bring torch)
CONFIGS = {
    "OnnxExportConfig": "loosefit.inference.onnx.export",
    "EngineExportConfig": "loosefit.inference.engine.export",
}


def __getattr__(name: str):
    """:class:`~loosefit.inference.onnx.export.OnnxExportConfig` (how the full runtime's
    graph is written: the opset, the detail stage, the check) and
    :class:`~loosefit.inference.engine.export.EngineExportConfig` (the engine tier's: the
    opset, the capsules, the check's frames), imported when first asked for."""
    if name in CONFIGS:
        from importlib import import_module

        return getattr(import_module(CONFIGS[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


@dataclass(frozen=True)
class ExportedModel:
    """The files a model's export wrote, and what its JSON records.

    Attributes:
        onnx: the graph.
        json: what its inputs and outputs mean (``metadata``, as written).
        obj: the garment's mesh (rest shape, faces, UVs; the graph's vertex order).
        metadata: the JSON's contents; its ``check`` (None: not checked) the check's
            figures, its ``capsules`` (the engine tier) the collider's capsules.
        tolerance: m, the largest difference from PyTorch the check allowed.
        checkpoint: the checkpoint exported (None: a model given in memory).
    """

    onnx: Path
    json: Path
    obj: Path
    metadata: dict
    tolerance: float
    checkpoint: Path | None = None
    residual: Path | None = None  # the set's residual process (``OUT.residual.npz``), if any

    @property
    def paths(self) -> list[Path]:
        """The ``.onnx``, ``.json`` and ``.obj`` paths (and ``.residual.npz``, if written)."""
        return [self.onnx, self.json, self.obj, *([self.residual] if self.residual else [])]

    @property
    def check(self) -> dict | None:
        """The check against PyTorch as recorded (None: not checked): ``onnxruntime`` (its
        version), ``max_difference_m``, ``frames`` (and, for the engine tier, ``motion``)."""
        return self.metadata.get("check")


def export_sequence(
    sequence: str | Path, out: str | Path, *, body: bool = True, config=None
) -> list[Path]:
    """A sequence ``.npz`` (from :meth:`~loosefit.api.Animator.animate`'s ``save``, the
    demo, or a data set's ``sequences/NAME.npz``) exported by ``out``'s suffix: ``.usd``,
    ``.usdc``, ``.usda``, ``.abc``, ``.glb``, ``.pc2`` (with OBJ), or a folder of OBJs
    (:meth:`~loosefit.sequence.GarmentSequence.export`).

    Args:
        sequence: the ``.npz`` file.
        out: the file or folder to write.
        body: the body too (False: the garment alone).
        config: the axes and the body's form
            (:class:`~loosefit.export.meshes.ExportConfig`; None: each format's own).

    Returns:
        The files written.

    Raises:
        LoosefitInputError: a file that is not a sequence ``.npz``, or an unknown suffix.
    """
    from loosefit.data.format import read_any_sequence

    path = Path(sequence)
    if path.suffix != ".npz":
        raise LoosefitInputError(
            path,
            "<file>",
            "a sequence .npz (from animate, the API, demo or a data set's sequences/)",
            "another file",
        )
    return read_any_sequence(path).export(out, body=body, config=config)


def _model_of(model):
    """The trained stages of ``model``: an :class:`~loosefit.api.Animator`'s, a checkpoint
    path's (:func:`loosefit.load`; None: the pretrained set), or ``model`` itself."""
    if model is None or isinstance(model, str | Path):
        from loosefit.api import load

        return load(model).model
    return getattr(model, "model", model)


def export_onnx(model, out: str | Path, *, config=None) -> ExportedModel:
    """A trained model's learned runtime (motion features, the motion encoder's step, the
    decoders, the detail generator) as one ONNX graph at ``out``, its GRU state and previous
    garment explicit inputs and outputs, with a JSON beside it saying what they mean and the
    garment's mesh as OBJ (:func:`~loosefit.inference.onnx.export.export_onnx`; all three
    files or none).

    Args:
        model: an :class:`~loosefit.api.Animator` (:func:`loosefit.load`), or a checkpoint
            path (None: the pretrained set).
        out: the ``.onnx`` file to write (``.json`` and ``.obj`` beside it).
        config: an ``OnnxExportConfig`` (of this module): the opset (16-20), the detail
            stage in the graph (when the model has one), and the check (the rest pose, then
            a bent one, through onnxruntime against PyTorch before the files are kept) and
            its tolerance. None: its defaults.

    Returns:
        :class:`ExportedModel`.

    Raises:
        LoosefitInputError: a stage the graph does not support (a baseline), a path not
            ``.onnx``, the ``onnx`` extra missing (``pip install 'loosefit[onnx]'``), or a
            graph that differs from PyTorch.
    """
    from loosefit.inference.onnx.export import OnnxExportConfig
    from loosefit.inference.onnx.export import export_onnx as export

    config = config or OnnxExportConfig()
    checkpoint = _checkpoint_of(model)
    stages = _model_of(model)
    onnx_path, json_path, obj_path = export(stages, out, config)
    meta = json.loads(json_path.read_text())
    residual = None
    if getattr(stages, "residual", None) is not None:
        residual = write_residual(stages.residual, onnx_path.with_suffix(".residual.npz"))
    return ExportedModel(
        onnx_path, json_path, obj_path, meta, config.tolerance, checkpoint, residual
    )


def write_residual(process, path: str | Path) -> Path:
    """A residual process (:mod:`loosefit.model.residual`) as ``.npz`` for an engine that
    draws realisations itself: ``basis`` (K, V, 3) float32, ``std`` (K,) m, ``correlation``
    rho, ``scale`` s and ``gain`` (a, b). A realisation's offset at frame t is ``s * m_t *
    sum_k std_k c_tk basis_k`` (c_t = rho c_t-1 + sqrt(1 - rho^2) e_t, e_t standard normal;
    m_t = clamp(a + b w_t, 0.1, 4), w_t the motion's intensity, ``motion_intensity``), in the root
    frame: turned by the frame's heading and added to the graph's world garment, never to
    the garment the graph is fed back (docs/use/ENGINE_EXPORT.md)."""
    import numpy as np

    from loosefit.atomic import atomic_path

    path = Path(path)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez(
                f,
                basis=process.basis.numpy().astype(np.float32),
                std=process.std.numpy().astype(np.float32),
                correlation=np.float64(process.config.correlation),
                scale=np.float64(process.config.scale),
                gain=np.asarray(process.gain, np.float64),
            )
    return path


def _checkpoint_of(model) -> Path | None:
    """The checkpoint ``model`` was read from, where known."""
    if model is None:
        from loosefit.api import pretrained_checkpoint

        return pretrained_checkpoint()
    if isinstance(model, str | Path):
        return Path(model)
    path = getattr(model, "path", None)
    return Path(path) if path is not None else None


def engine_checkpoint(checkpoint: str | Path | None = None) -> Path:
    """The engine tier of a checkpoint: itself if it is one, else ``engine.pt`` beside it
    (None: the pretrained set's).

    Raises:
        LoosefitInputError: neither, saying how to train one.
    """
    from loosefit.api import pretrained_checkpoint
    from loosefit.inference.checkpoints import checkpoint_format
    from loosefit.inference.engine.model import ENGINE_FORMAT, engine_path_of

    checkpoint = Path(checkpoint) if checkpoint is not None else pretrained_checkpoint()
    if checkpoint.is_file() and checkpoint_format(checkpoint) == ENGINE_FORMAT:
        return checkpoint
    beside = engine_path_of(checkpoint)
    if beside.is_file():
        return beside
    raise LoosefitInputError(
        checkpoint,
        "tier",
        f"an engine tier: an engine-tier checkpoint, or {beside.name} beside it",
        f"no {beside}",
        hint=f"train one: loosefit train engine --data DATASET --motion {checkpoint} "
        f"--out RUN, then pass --checkpoint RUN/engine.pt (or copy it to {beside})",
    )


def export_engine(checkpoint: str | Path | None, out: str | Path, *, config=None) -> ExportedModel:
    """The engine tier, a linear garment basis with capsules for the engine's collider, as
    one ONNX graph a frame at ``out``, its JSON (with the capsules) and the garment's mesh
    beside it (:func:`~loosefit.inference.engine.export.export_engine`; all three files or
    none).

    Args:
        checkpoint: an engine-tier checkpoint, or one with ``engine.pt`` beside it (a set's
            ``motion.pt``; None: the pretrained set's), as :func:`engine_checkpoint` finds.
        out: the ``.onnx`` file to write (``.json`` and ``.obj`` beside it).
        config: an ``EngineExportConfig`` (of this module): the opset, the capsules, the
            frames of a procedural dance run through onnxruntime's reference loop against
            PyTorch before the files are kept (0: none) and the tolerance. None: its
            defaults.

    Returns:
        :class:`ExportedModel`, its ``checkpoint`` the engine tier's file.

    Raises:
        LoosefitInputError: no engine tier (saying how to train one), a path not
            ``.onnx``, a missing package, or a graph that differs from PyTorch.
    """
    from loosefit.inference.engine.export import EngineExportConfig
    from loosefit.inference.engine.export import export_engine as export
    from loosefit.inference.engine.model import load_engine

    config = config or EngineExportConfig()
    path = engine_checkpoint(checkpoint)
    onnx_path, json_path, obj_path = export(load_engine(path), out, config)
    meta = json.loads(json_path.read_text())
    return ExportedModel(onnx_path, json_path, obj_path, meta, config.tolerance, path)
