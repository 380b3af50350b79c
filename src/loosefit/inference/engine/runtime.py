"""The engine tier's reference loop: onnxruntime and numpy alone (no torch import).

::

    from loosefit.inference.engine.runtime import EngineRuntime, rollout_engine_onnx

    runtime = EngineRuntime("engine.onnx", threads=1)    # reads engine.json beside it
    runtime.check_skeleton(my_joint_names)               # the engine's skeleton, in order
    state = runtime.initial_state(B)
    for t in range(frames):
        garment, state = runtime.step(rotations[:, t], roots[:, t], state, start=(t == 0))
        # garment (B, V, 3), pushed out of the capsules in the graph: the renderer

The graph's inputs and outputs are listed in :mod:`loosefit.inference.engine.export`.
"""

from __future__ import annotations

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.inference.onnx.runtime import OnnxRuntime, check_diverged
from loosefit.inference.timeline import rollout_timeline
from loosefit.types import Motion

FORMAT = "loosefit-onnx-engine/1"  # as loosefit.inference.engine.export.FORMAT


class EngineRuntime(OnnxRuntime):
    """The engine tier's graph in an onnxruntime session, with its JSON: an
    :class:`~loosefit.inference.onnx.runtime.OnnxRuntime` (``initial_state``, ``step``: the
    garments (B, V, 3), world, pushed out of the capsules unless exported without) that also
    checks an engine's skeleton against the JSON's.

    Args:
        path: the ``.onnx`` file (its ``.json`` beside it, or ``meta_path``).
        threads: onnxruntime's intra-op threads (1: one core, as a game thread has).

    Raises:
        LoosefitInputError: onnxruntime missing, or a missing or unreadable graph or JSON.
    """

    FORMAT = FORMAT
    COMMAND = "loosefit export-model --tier engine"

    def check_skeleton(self, joint_names, source: str = "skeleton") -> None:
        """Refuse a skeleton whose joint names or order differ from the JSON's.

        Raises:
            LoosefitInputError: naming the first joint that differs.
        """
        mine, theirs = self.joint_names, list(joint_names)
        for j, (a, b) in enumerate(zip(mine, theirs, strict=False)):
            if a != b:
                raise LoosefitInputError(
                    source,
                    f"joint_names[{j}]",
                    repr(a),
                    repr(b),
                    hint=f"the {len(mine)} joints of {self.path.with_suffix('.json').name}, "
                    "in its order (retarget, or reorder the rotations)",
                )
        if len(mine) != len(theirs):
            j = min(len(mine), len(theirs))
            raise LoosefitInputError(
                source,
                f"joint_names[{j}]",
                repr(mine[j]) if j < len(mine) else "no more joints",
                repr(theirs[j]) if j < len(theirs) else "no more joints",
                hint=f"the {len(mine)} joints of {self.path.with_suffix('.json').name}",
            )


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
        raise LoosefitInputError(
            f"motion '{motion.name}'",
            "fps",
            f"{runtime.fps:g}",
            f"{motion.fps:g}",
            hint="resample it",
        )
    s = meta["start_of_motion"]
    rot, root, P = rollout_timeline(
        motion, float(meta["floor_height"]), int(s["warm_frames"]), float(s["blend_seconds"])
    )
    rot, root = rot.astype(np.float32), root.astype(np.float32)
    out = np.empty((motion.num_frames, int(meta["vertex_count"]), 3), np.float32)
    state = runtime.initial_state(1)
    for t in range(len(rot)):
        garment, state = runtime.step(rot[t : t + 1], root[t : t + 1], state, start=t == 0)
        check_diverged(garment, root[t : t + 1], meta["max_distance"], f"frame {t - P}")
        if t >= P:
            out[t - P] = garment[0]
    return out
