"""The exported graph driven by onnxruntime and numpy alone: the reference step loop an
engine follows (no torch is imported here; docs/use/ENGINE_EXPORT.md).

::

    from loosefit.inference.onnx.runtime import OnnxRuntime, rollout_onnx

    runtime = OnnxRuntime("salsa.onnx", threads=1)   # reads salsa.json beside it
    garments = rollout_onnx(runtime, motion)         # (T, V, 3), world positions

or frame by frame, as an engine does (B characters at once)::

    state = runtime.initial_state(B)
    for t in range(frames):
        garment, state = runtime.step(rotations[:, t], roots[:, t], state, start=(t == 0))
        # garment (B, V, 3): the engine's collider, then the renderer

The graph's inputs and outputs are listed in :mod:`loosefit.inference.onnx.export`.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.inference.timeline import rollout_timeline
from loosefit.types import Motion

FORMAT = "loosefit-onnx-step/1"  # as loosefit.inference.onnx.export.FORMAT


class OnnxDivergedError(RuntimeError):
    """A garment with NaN or a vertex farther than ``max_distance`` from the root."""


def read_metadata(
    path: str | Path,
    format: str = FORMAT,
    command: str = "loosefit export-model",
    meta_path: str | Path | None = None,
) -> dict:
    """The JSON written beside an exported graph (``path`` with ``.json``, or ``meta_path``),
    checked to be of ``format`` (what ``command`` writes).

    Raises:
        LoosefitInputError: a missing or unreadable file, or another format.
    """
    meta_path = Path(meta_path) if meta_path else Path(path).with_suffix(".json")
    if not meta_path.is_file():
        raise LoosefitInputError(
            meta_path,
            "<file>",
            f"the JSON written beside the .onnx by {command}",
            "no such file",
        )
    try:
        meta = json.loads(meta_path.read_text())
    except (OSError, ValueError) as exc:
        raise LoosefitInputError(meta_path, "<file>", "JSON", str(exc)) from None
    if not isinstance(meta, dict) or meta.get("format") != format:
        found = meta.get("format") if isinstance(meta, dict) else type(meta).__name__
        raise LoosefitInputError(
            meta_path, "format", repr(format), repr(found), hint=f"an export of {command}"
        )
    return meta


class OnnxRuntime:
    """An exported graph in an onnxruntime session, with its JSON.

    Args:
        path: the ``.onnx`` file (its ``.json`` beside it, or ``meta_path``).
        threads: onnxruntime's intra-op threads (1: one core, as a game thread has).

    Raises:
        LoosefitInputError: onnxruntime missing, or a missing or unreadable graph or JSON.
    """

    FORMAT = FORMAT  # the JSON's format, and the command that writes such a graph
    COMMAND = "loosefit export-model"

    def __init__(
        self, path: str | Path, threads: int = 1, meta_path: str | Path | None = None
    ) -> None:
        try:
            import onnxruntime as ort
        except ImportError:
            raise LoosefitInputError(
                path,
                "<dependencies>",
                "onnxruntime (pip install 'loosefit[onnx]')",
                "not installed",
            ) from None
        self.path = Path(path)
        if not self.path.is_file():
            raise LoosefitInputError(self.path, "<file>", "an exported .onnx graph", "no such file")
        self.meta = read_metadata(self.path, self.FORMAT, self.COMMAND, meta_path)
        options = ort.SessionOptions()
        options.intra_op_num_threads = threads
        options.inter_op_num_threads = 1
        self.session = ort.InferenceSession(
            str(self.path), options, providers=["CPUExecutionProvider"]
        )
        self.outputs = [o.name for o in self.session.get_outputs()]
        self.inputs = [i.name for i in self.session.get_inputs()]
        if self.inputs != list(self.meta["inputs"]):
            raise LoosefitInputError(
                self.path, "inputs", f"the JSON's {list(self.meta['inputs'])}", str(self.inputs)
            )
        self.state_of = dict(self.meta["state"])  # output -> input

    @property
    def joint_names(self) -> list[str]:
        return list(self.meta["joint_names"])

    @property
    def fps(self) -> float:
        return float(self.meta["frame_rate"])

    def initial_state(self, batch: int) -> dict[str, np.ndarray]:
        """The state inputs before a first frame (zeros: ``start`` makes the graph ignore them)."""
        shapes = self.meta["inputs"]
        return {
            name: np.zeros([batch, *shapes[name]["shape"][1:]], np.float32)
            for name in self.state_of.values()
        }

    def step(
        self,
        rotations: np.ndarray,
        root: np.ndarray,
        state: dict[str, np.ndarray],
        start: bool | np.ndarray = False,
    ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """One frame for B characters.

        Args:
            rotations: (B, J, 3, 3) local joint rotations, in ``joint_names``' order.
            root: (B, 3) root positions, world.
            state: the state of the frame before (:meth:`initial_state` before the first).
            start: (B,) or one bool: a character's first frame.

        Returns:
            The garments (B, V, 3), world positions, and the next frame's state.
        """
        B = len(rotations)
        feed = {
            "joint_rotations": np.ascontiguousarray(rotations, np.float32),
            "root_translation": np.ascontiguousarray(root, np.float32),
            "start": np.broadcast_to(np.asarray(start, bool), (B,)).copy(),
            **state,
        }
        out = dict(zip(self.outputs, self.session.run(None, feed), strict=True))
        return out["garment"], {self.state_of[k]: out[k] for k in self.state_of}


def check_diverged(garment: np.ndarray, root: np.ndarray, limit: float, where: str) -> None:
    """Raise :class:`OnnxDivergedError` on NaN in garments (B, V, 3) or a vertex farther
    than ``limit`` m from its root (B, 3)."""
    far = np.linalg.norm(garment - root[:, None], axis=-1).max()
    if not far <= limit:
        raise OnnxDivergedError(
            f"rollout diverged at {where}: a vertex is {far:.2f} m from "
            f"the root (limit {limit} m) or NaN"
        )


def rollout_onnx(
    runtime: OnnxRuntime, motion: Motion, progress: Callable[[int, int], None] | None = None
) -> np.ndarray:
    """The garment through ``motion`` as :func:`loosefit.inference.rollout.rollout` computes it
    without detail-stage feedback, edge lengths or collision handling: the rest pose, the
    blend into the motion (the JSON's ``start_of_motion``), then one graph call per frame.

    Args:
        runtime: the exported graph.
        motion: T frames on the graph's joints, at its frame rate.
        progress: called as ``progress(done, total)`` every frame.

    Returns:
        (T, V, 3) float32 world positions of the motion's frames (after the detail
        stage, when the graph has it).

    Raises:
        LoosefitInputError: a motion on other joints or at another frame rate.
        OnnxDivergedError: NaN or a vertex past the JSON's ``max_distance``.
    """
    meta = runtime.meta
    if list(motion.joint_names) != runtime.joint_names:
        raise LoosefitInputError(
            f"motion '{motion.name}'",
            "joint_names",
            f"the graph's {len(runtime.joint_names)} joints, in order",
            f"{len(motion.joint_names)} joints",
        )
    if abs(motion.fps - runtime.fps) > 1e-6:
        raise LoosefitInputError(
            f"motion '{motion.name}'",
            "fps",
            f"{runtime.fps:g}",
            f"{motion.fps:g}",
            hint="resample it",
        )
    start = meta["start_of_motion"]
    rot, root, P = rollout_timeline(
        motion,
        float(meta["floor_height"]),
        int(start["warm_frames"]),
        float(start["blend_seconds"]),
    )
    total = len(rot)
    out = np.empty((motion.num_frames, int(meta["vertex_count"]), 3), np.float32)
    state = runtime.initial_state(1)
    for t in range(total):
        garment, state = runtime.step(rot[t : t + 1], root[t : t + 1], state, start=t == 0)
        where = f"motion frame {t - P}" if t >= P else f"preroll frame {t}"
        check_diverged(garment, root[t : t + 1], meta["max_distance"], where)
        if t >= P:
            out[t - P] = garment[0]
        if progress is not None:
            progress(t + 1, total)
    return out
