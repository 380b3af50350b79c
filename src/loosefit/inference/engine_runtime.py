"""The engine tier's reference loop: onnxruntime and numpy alone (no torch import).

::

    from loosefit.inference.engine_runtime import EngineRuntime, rollout_engine_onnx

    runtime = EngineRuntime("engine.onnx", threads=1)    # reads engine.json beside it
    runtime.check_skeleton(my_joint_names)               # the engine's skeleton, in order
    state = runtime.initial_state(B)
    for t in range(frames):
        garment, state = runtime.step(rotations[:, t], roots[:, t], state, start=(t == 0))
        # garment (B, V, 3), pushed out of the capsules in the graph: the renderer

The graph's inputs and outputs are listed in :mod:`loosefit.inference.engine_export`.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.inference.onnx_runtime import check_diverged
from loosefit.inference.timeline import rollout_timeline
from loosefit.types import Motion

FORMAT = "loosefit-onnx-engine/1"  # as loosefit.inference.engine_export.FORMAT


def read_engine_metadata(path: Path) -> dict:
    """The engine tier's JSON, checked to be one.

    Raises:
        LoosefitInputError: missing, unreadable, or of another format.
    """
    if not path.is_file():
        raise LoosefitInputError(path, "<file>", "the JSON written beside the .onnx by "
                                 "loosefit export-model --tier engine", "no such file")  # fmt: skip
    try:
        meta = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise LoosefitInputError(path, "<file>", "JSON", str(exc)) from None
    found = meta.get("format") if isinstance(meta, dict) else type(meta).__name__
    if found != FORMAT:
        raise LoosefitInputError(path, "format", repr(FORMAT), repr(found),
                                 hint="an export of --tier engine")  # fmt: skip
    return meta


class EngineRuntime:
    """The engine tier's graph in an onnxruntime session, with its JSON.

    Args:
        path: the ``.onnx`` file (its ``.json`` beside it, or ``meta_path``).
        threads: onnxruntime's intra-op threads (1: one core, as a game thread has).

    Raises:
        LoosefitInputError: onnxruntime missing, or a missing or unreadable graph or JSON.
    """

    def __init__(self, path: str | Path, threads: int = 1, meta_path: str | Path | None = None):
        try:
            import onnxruntime as ort
        except ImportError:
            raise LoosefitInputError(path, "<dependencies>", "onnxruntime (pip install "
                                     "'loosefit[onnx]')", "not installed") from None  # fmt: skip
        self.path = Path(path)
        if not self.path.is_file():
            raise LoosefitInputError(self.path, "<file>", "an exported .onnx graph", "no such file")
        self.meta = read_engine_metadata(Path(meta_path or self.path.with_suffix(".json")))
        options = ort.SessionOptions()
        options.intra_op_num_threads = threads
        options.inter_op_num_threads = 1
        self.session = ort.InferenceSession(str(self.path), options,
                                            providers=["CPUExecutionProvider"])  # fmt: skip
        self.outputs = [o.name for o in self.session.get_outputs()]
        self.state_of = dict(self.meta["state"])  # output -> input

    @property
    def joint_names(self) -> list[str]:
        return list(self.meta["joint_names"])

    @property
    def fps(self) -> float:
        return float(self.meta["frame_rate"])

    def check_skeleton(self, joint_names, source: str = "skeleton") -> None:
        """Refuse a skeleton whose joint names or order differ from the JSON's.

        Raises:
            LoosefitInputError: naming the first joint that differs.
        """
        mine, theirs = self.joint_names, list(joint_names)
        for j, (a, b) in enumerate(zip(mine, theirs, strict=False)):
            if a != b:
                raise LoosefitInputError(
                    source, f"joint_names[{j}]", repr(a), repr(b),
                    hint=f"the {len(mine)} joints of {self.path.with_suffix('.json').name}, "
                    "in its order (retarget, or reorder the rotations)",
                )  # fmt: skip
        if len(mine) != len(theirs):
            j = min(len(mine), len(theirs))
            raise LoosefitInputError(
                source, f"joint_names[{j}]",
                repr(mine[j]) if j < len(mine) else "no more joints",
                repr(theirs[j]) if j < len(theirs) else "no more joints",
                hint=f"the {len(mine)} joints of {self.path.with_suffix('.json').name}",
            )  # fmt: skip

    def initial_state(self, batch: int) -> dict[str, np.ndarray]:
        """The state inputs before a first frame (zeros: ``start`` makes the graph ignore them)."""
        shapes = self.meta["inputs"]
        return {name: np.zeros([batch, *shapes[name]["shape"][1:]], np.float32)
                for name in self.state_of.values()}  # fmt: skip

    def step(
        self,
        rotations: np.ndarray,
        root: np.ndarray,
        state: dict[str, np.ndarray],
        start: bool | np.ndarray = False,
    ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """One frame for B characters: the garments (B, V, 3) before collision, world, and
        the next frame's state.

        Args:
            rotations: (B, J, 3, 3) float32 local joint rotations, in ``joint_names``' order.
            root: (B, 3) root positions, world.
            state: the state of the frame before (:meth:`initial_state` before the first).
            start: (B,) or one bool: a character's first frame.
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


def rollout_engine_onnx(runtime: EngineRuntime, motion: Motion) -> np.ndarray:
    """The engine tier's garment through ``motion``: the rest pose, the blend into the motion
    (the JSON's ``start_of_motion``), one graph call per frame (the capsule push-out in it,
    unless exported without).

    Returns:
        (T, V, 3) float32 world positions of the motion's frames.

    Raises:
        LoosefitInputError: a motion on another skeleton (the first joint that differs) or
            at another frame rate.
    """
    meta = runtime.meta
    runtime.check_skeleton(motion.joint_names, f"motion '{motion.name}'")
    if abs(motion.fps - runtime.fps) > 1e-6:
        raise LoosefitInputError(f"motion '{motion.name}'", "fps", f"{runtime.fps:g}",
                                 f"{motion.fps:g}", hint="resample it")  # fmt: skip
    s = meta["start_of_motion"]
    rot, root, P = rollout_timeline(motion, float(meta["floor_height"]), int(s["warm_frames"]),
                                    float(s["blend_seconds"]))  # fmt: skip
    rot, root = rot.astype(np.float32), root.astype(np.float32)
    out = np.empty((motion.num_frames, int(meta["vertex_count"]), 3), np.float32)
    state = runtime.initial_state(1)
    for t in range(len(rot)):
        garment, state = runtime.step(rot[t : t + 1], root[t : t + 1], state, start=t == 0)
        check_diverged(garment, root[t : t + 1], meta["max_distance"], f"frame {t - P}")
        if t >= P:
            out[t - P] = garment[0]
    return out
