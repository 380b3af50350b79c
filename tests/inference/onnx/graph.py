"""A hand-made step graph of the exported interface (onnx.helper, no torch): the garment is
fixed offsets around the root, and its one state counts the frames since ``start``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

OFFSETS = np.array([[0.1, 0.0, -0.2], [-0.1, 0.05, -0.4], [0.0, -0.1, -0.6]], np.float32)
JOINTS = ["Hips", "Spine", "Head"]


def write_step_graph(path: Path, format: str, max_distance: float = 3.0) -> Path:
    """``path`` (.onnx) and its JSON: inputs joint_rotations (B, J, 3, 3), root_translation
    (B, 3), start (B,), frames_in (B, 1); outputs garment = root + OFFSETS (B, V, 3) and
    frames_out = (0 if start else frames_in) + 1."""
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    J, V = len(JOINTS), len(OFFSETS)
    f32 = TensorProto.FLOAT
    inputs = [
        helper.make_tensor_value_info("joint_rotations", f32, ["B", J, 3, 3]),
        helper.make_tensor_value_info("root_translation", f32, ["B", 3]),
        helper.make_tensor_value_info("start", TensorProto.BOOL, ["B"]),
        helper.make_tensor_value_info("frames_in", f32, ["B", 1]),
    ]
    outputs = [
        helper.make_tensor_value_info("garment", f32, ["B", V, 3]),
        helper.make_tensor_value_info("frames_out", f32, ["B", 1]),
    ]
    consts = [
        numpy_helper.from_array(OFFSETS[None], "offsets"),
        numpy_helper.from_array(np.array([1], np.int64), "axis1"),
        numpy_helper.from_array(np.zeros((1, 1), np.float32), "zero"),
        numpy_helper.from_array(np.ones((1, 1), np.float32), "one"),
    ]
    nodes = [
        helper.make_node("Unsqueeze", ["root_translation", "axis1"], ["root3"]),
        helper.make_node("Add", ["root3", "offsets"], ["garment"]),
        helper.make_node("Unsqueeze", ["start", "axis1"], ["start2"]),
        helper.make_node("Where", ["start2", "zero", "frames_in"], ["kept"]),
        helper.make_node("Add", ["kept", "one"], ["frames_out"]),
    ]
    graph = helper.make_graph(nodes, "step", inputs, outputs, consts)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    onnx.save(model, str(path))
    meta = {
        "format": format,
        "joint_names": JOINTS,
        "frame_rate": 30.0,
        "vertex_count": V,
        "floor_height": 0.9,
        "max_distance": max_distance,
        "start_of_motion": {"warm_frames": 3, "blend_seconds": 0.1},
        "inputs": {
            "joint_rotations": {"shape": ["B", J, 3, 3]},
            "root_translation": {"shape": ["B", 3]},
            "start": {"shape": ["B"]},
            "frames_in": {"shape": ["B", 1]},
        },
        "state": {"frames_out": "frames_in"},
    }
    path.with_suffix(".json").write_text(json.dumps(meta))
    return path


def walk(T: int = 5, fps: float = 30.0, joints: list[str] | None = None):
    """A motion of T frames on ``joints`` (default JOINTS), the root walking along +X."""
    from loosefit.types import Motion

    names = joints or JOINTS
    rot = np.tile(np.eye(3, dtype=np.float32), (T, len(names), 1, 1))
    root = np.stack([0.1 * np.arange(T), np.zeros(T), np.full(T, 0.95)], 1)
    return Motion(names, rot, root, fps, "walk")
