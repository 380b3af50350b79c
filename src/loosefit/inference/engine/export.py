"""The engine tier as one ONNX graph, with the capsules an engine collides it with.

One call of the graph is one frame for B characters::

    inputs                     shape          outputs                   shape
    joint_rotations            (B, J, 3, 3)   garment                   (B, V, 3)
    root_translation           (B, 3)         next_hidden               (B, G)
    start                      (B,) bool      next_coefficients         (B, K)
    hidden                     (B, G)         next_root_rotation        (B, 3, 3)
    previous_coefficients      (B, K)         next_root_translation     (B, 3)
    previous_root_rotation     (B, 3, 3)
    previous_root_translation  (B, 3)

In the graph: the motion features (:func:`~loosefit.model.motion_features.frame_features`),
the tier's step (:class:`~loosefit.model.engine.EngineTier`) and the decoding, one matrix
product, into world positions. ``start`` marks a character's first frame (the settled
drape's coefficients, a zero state, no velocity). Collision: the JSON beside the graph
lists capsules fitted to the avatar (:mod:`loosefit.body.capsules`) on the joints of the
engine's skeleton, and the graph pushes the garment out of them
(:func:`loosefit.geometry.capsule.push_out`, the segments placed by the frame's joint
rotations), unless exported without (``capsules=False``: the engine's own collider does it
with the JSON's capsules). The waistband is glued to the body in the simulation and held
by the full pipeline; capsules are rounder than a waist, so the trunk's capsules leave the
band where the tier puts it and push gradually more below it (:func:`waist_hold`); the
legs' push it as the rest. Measured:
in the graph the push-out costs a fraction of what the same steps cost as numpy calls
(docs/use/ENGINE_EXPORT.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn

from loosefit.errors import LoosefitInputError
from loosefit.geometry.capsule import chain_frames, push_out
from loosefit.inference.onnx.export import (
    check_onnx_target,
    graph_header,
    write_graph_files,
)
from loosefit.model.motion_features import (
    frame_features,
    from_root_frame,
    heading_yaw,
    yaw_matrix,
)

FORMAT = "loosefit-onnx-engine/1"  # the JSON's "format"
# the capsules of the trunk, which the waistband is glued to: their push-out leaves the band
# (waist_hold); a leg's capsule pushes it as any cloth (a thigh raised to the waist)
TRUNK = ("pelvis", "abdomen", "waist")
INPUTS = (
    "joint_rotations",
    "root_translation",
    "start",
    "hidden",
    "previous_coefficients",
    "previous_root_rotation",
    "previous_root_translation",
)
OUTPUTS = (
    "garment",
    "next_hidden",
    "next_coefficients",
    "next_root_rotation",
    "next_root_translation",
)
STATE = {  # output -> the input it becomes on the next frame
    "next_hidden": "hidden",
    "next_coefficients": "previous_coefficients",
    "next_root_rotation": "previous_root_rotation",
    "next_root_translation": "previous_root_translation",
}


@dataclass(frozen=True)
class EngineExportConfig:
    """How the engine tier's graph is written."""

    opset: int = 17  # the ONNX operator set the graph is written in
    capsules: bool = True  # the capsule push-out in the graph (False: the engine's own collider)
    check_frames: int = 300  # frames of a procedural dance run against PyTorch (0: none)
    tolerance: float = 1e-5  # m: the check's largest allowed difference
    waist_blend: float = 0.08  # m the push-out fades in over below the band; 0: band pushed too


def waist_hold(vertices: np.ndarray, waist: np.ndarray, blend: float) -> np.ndarray:
    """(V,) float32 the share of the capsule push-out each garment vertex takes: 0 on the
    waistband and at its height, rising linearly to 1 at ``blend`` metres below the band's
    mean height (+Z up) and below; ``blend`` 0: 1 everywhere (the band pushed out too).

    A round capsule is wider than a waist in places: pushing the band out of the waist's
    capsule loosened it by 4-5 cm and stood it out at the back, where the simulation glues
    it to the body.

    Args:
        vertices: (V, 3) the garment at rest (the template's, on the avatar).
        waist: (W,) the waistband's vertices.
        blend: metres (>= 0).
    """
    if not blend >= 0:
        raise LoosefitInputError("EngineExportConfig", "waist_blend", "metres >= 0", blend)
    if blend == 0:
        return np.ones(len(vertices), np.float32)
    z = np.asarray(vertices, np.float64)[:, 2]
    below = float(z[np.asarray(waist)].mean()) - z  # (V,) metres below the band
    return np.clip(below / blend, 0.0, 1.0).astype(np.float32)


class EngineStep(nn.Module):
    """One frame of the engine tier for B characters (the module docstring's graph).

    Args:
        model: an :class:`~loosefit.inference.engine.model.EngineModel`.
        capsules: the capsules to push the garment out of (None: no push-out).
        skeleton: what places them (:func:`skeleton_record`).
        waist_blend: metres below the waistband over which the push-out comes in
            (:func:`waist_hold`).
    """

    def __init__(
        self,
        model,
        capsules: list | None = None,
        skeleton: dict | None = None,
        waist_blend: float = EngineExportConfig.waist_blend,
    ):
        super().__init__()
        self.tier = model.tier
        self.fps, self.floor_height = float(model.fps), float(model.floor_height)
        self.joints = model.joints
        self.collide = capsules is not None
        if self.collide:
            names = list(model.joint_names)
            self.capsule_joints = [names.index(c.joint) for c in capsules]
            self.parents = [int(p) for p in skeleton["parents"]]
            self.register_buffer("offsets", torch.tensor(skeleton["offsets"], dtype=torch.float32))
            self.register_buffer("capsule_start", torch.tensor([c.start for c in capsules]))
            self.register_buffer("capsule_end", torch.tensor([c.end for c in capsules]))
            self.register_buffer("radius", torch.tensor([c.radius for c in capsules]))
            hold = waist_hold(model.template.vertices, model.template.waist, waist_blend)
            trunk = torch.tensor([c.name in TRUNK for c in capsules])  # (C,)
            weight = torch.where(trunk, torch.from_numpy(hold)[:, None], torch.ones(1))
            self.register_buffer("push_weight", weight)  # (V, C)

    def forward(
        self,
        joint_rotations,
        root_translation,
        start,
        hidden,
        previous_coefficients,
        previous_root_rotation,
        previous_root_translation,
    ):
        """The inputs and outputs of the module docstring, in that order."""
        root_rotation = joint_rotations[:, 0]  # (B, 3, 3)
        first = start[:, None]  # (B, 1)
        before_rot = torch.where(first[..., None], root_rotation, previous_root_rotation)
        before_root = torch.where(first, root_translation, previous_root_translation)
        feats = frame_features(
            joint_rotations, root_translation, before_rot, before_root,
            self.fps, self.floor_height, joints=self.joints,
        )  # fmt: skip  # (B, F)
        previous = torch.where(first, self.tier.rest, previous_coefficients)  # (B, K)
        hidden = torch.where(first, torch.zeros_like(hidden), hidden)
        c, hidden = self.tier(feats, previous, hidden)
        H = yaw_matrix(heading_yaw(root_rotation))  # (B, 3, 3)
        garment = from_root_frame(self.tier.decode(c), H, root_translation)  # (B, V, 3)
        if self.collide:
            R, p = chain_frames(joint_rotations, root_translation, self.parents, self.offsets,
                                self.capsule_joints)  # fmt: skip  # (B, C, 3, 3), (B, C, 3)
            a = (R @ self.capsule_start[..., None])[..., 0] + p  # (B, C, 3)
            b = (R @ self.capsule_end[..., None])[..., 0] + p
            garment = push_out(garment, a, b, self.radius, root_translation, self.push_weight)
        return garment, hidden, c, root_rotation, root_translation


def example_inputs(model, batch: int = 1) -> dict[str, np.ndarray]:
    """Inputs of a first frame (``start`` set) in the rest pose: numpy arrays by name."""
    J, G, K = len(model.joint_names), model.tier.config.gru, model.tier.config.basis
    rot = np.broadcast_to(np.eye(3, dtype=np.float32), (batch, J, 3, 3)).copy()
    root = np.tile(np.array([0.0, 0.0, model.floor_height], np.float32), (batch, 1))
    return {
        "joint_rotations": rot,
        "root_translation": root,
        "start": np.ones(batch, bool),
        "hidden": np.zeros((batch, G), np.float32),
        "previous_coefficients": np.zeros((batch, K), np.float32),
        "previous_root_rotation": rot[:, 0].copy(),
        "previous_root_translation": root.copy(),
    }


def skeleton_record(avatar) -> dict:
    """The skeleton the capsules hang on: parents and rest offsets, in the joints' order."""
    sk = avatar.skeleton
    heads = np.asarray(sk.heads, np.float64)
    parents = np.asarray(sk.parents, np.int64)
    offsets = np.where(parents[:, None] >= 0, heads - heads[np.maximum(parents, 0)], heads)
    return {
        "parents": parents.tolist(),
        "offsets": np.round(offsets, 6).tolist(),
        "frames": "G_root = [R_root | root_translation]; G_j = G_parent * T(offsets[j]) * "
        "R_j with R_j the joint's local rotation: a frame at the joint, the world's axes at "
        "rest (loosefit.body.capsules.joint_frames)",
    }


def export_metadata(
    model,
    onnx_name: str,
    opset: int,
    capsules: list,
    skeleton: dict,
    in_graph: bool,
    *,
    waist_blend: float = EngineExportConfig.waist_blend,
) -> dict:
    """What the graph's inputs and outputs mean, the skeleton and the capsules: the JSON."""
    J, V = len(model.joint_names), model.template.num_vertices
    G, K = model.tier.config.gru, model.tier.config.basis
    rc = model.rollout_config
    f32 = "float32"

    def io(shape, dtype, meaning):
        return {"shape": shape, "dtype": dtype, "meaning": meaning}

    return {
        **graph_header(model, FORMAT, onnx_name, opset),
        "tier": "engine",
        "hidden_size": G,
        "basis_size": K,
        "inputs": {
            "joint_rotations": io(["B", J, 3, 3], f32, "this frame's local joint rotations"),
            "root_translation": io(["B", 3], f32, "this frame's root joint position, world"),
            "start": io(
                ["B"],
                "bool",
                "true on a character's first frame: the state inputs "
                "are then not read (settled drape, zero state, no velocity)",
            ),
            "hidden": io(["B", G], f32, "next_hidden of the frame before"),
            "previous_coefficients": io(["B", K], f32, "next_coefficients of the frame before"),
            "previous_root_rotation": io(
                ["B", 3, 3],
                f32,
                "next_root_rotation of the frame before (the root's joint_rotations[:, 0])",
            ),
            "previous_root_translation": io(
                ["B", 3], f32, "next_root_translation of the frame before"
            ),
        },
        "outputs": {
            "garment": io(
                ["B", V, 3],
                f32,
                "the garment's vertices, world, pushed out of the capsules: render these"
                if in_graph
                else "the garment's vertices, "
                "world, before collision: push them out of the engine's capsules, "
                "then render",
            ),
            "next_hidden": io(["B", G], f32, "the recurrent state: the next frame's hidden"),
            "next_coefficients": io(
                ["B", K],
                f32,
                "the garment's basis coefficients (root "
                "frame, before collision): the next frame's "
                "previous_coefficients",
            ),
            "next_root_rotation": io(["B", 3, 3], f32, "the next frame's previous_root_rotation"),
            "next_root_translation": io(
                ["B", 3], f32, "the next frame's previous_root_translation"
            ),
        },
        "state": dict(STATE),
        "skeleton": skeleton,
        "capsules": [c.to_dict() for c in capsules],
        "capsules_in_graph": in_graph,
        "capsule_meaning": "start and end are the segment's end points in the frame of "
        "joint (skeleton.frames), radius in metres: push every garment vertex closer than "
        "radius to the segment out to its surface, along the direction from the nearest "
        "point of the segment, summed over the capsules it is in; the moves of the capsules "
        "named in waist_held_by times the vertex's share: 0 on the waistband and at its "
        "height, rising linearly to 1 at waist_blend metres below the band's mean height in "
        "the OBJ (loosefit.geometry.capsule.push_out, loosefit.inference.engine.export."
        "waist_hold; in the graph unless exported with --no-capsules)",
        "waist_held_by": list(TRUNK),
        "waist_blend": float(waist_blend),
        "start_of_motion": {
            "warm_frames": int(rc.warm_frames),
            "blend_seconds": float(rc.blend_seconds),
            "meaning": "as trained: the avatar stands in the rest pose for warm_frames frames, "
            "the first with start=true, then blends into the motion's first frame over "
            "blend_seconds: loosefit.motion.chain.preroll",
        },
        "max_distance": float(rc.max_distance),
    }


def check_engine_exportable(model, source) -> None:
    """A clear error unless ``model`` is an engine tier, saying how to train one.

    Raises:
        LoosefitInputError: anything else.
    """
    from loosefit.inference.engine.model import EngineModel

    if not isinstance(model, EngineModel):
        raise LoosefitInputError(
            source,
            "tier",
            "a model with an engine tier (engine.pt)",
            f"{type(model).__name__}, which has none",
            hint="train one: loosefit train engine --data DATASET --motion MOTION.pt "
            "(writes RUN/engine.pt; put it beside motion.pt or pass --checkpoint)",
        )
    if model.tier.config.noise:
        raise LoosefitInputError(
            source,
            "tier",
            "a deterministic engine tier (noise 0)",
            f"a stochastic one ({model.tier.config.noise} noise numbers a frame)",
            hint="the graph has no noise input yet: export a tier trained without --noise",
        )


def export_engine(model, path: str | Path, config: EngineExportConfig | None = None) -> list[Path]:
    """Write the engine tier as ONNX at ``path``, its JSON (``.json``) and the garment's mesh
    (``.obj``), all three or none; before keeping them, ``config.check_frames`` frames of a
    procedural dance run through onnxruntime's reference loop and PyTorch must agree within
    ``config.tolerance``.

    Returns:
        The three paths written.

    Raises:
        LoosefitInputError: not an engine tier, a path not ``.onnx``, a missing package, or
            a graph that differs from PyTorch.
    """
    config = config or EngineExportConfig()
    path = Path(path)
    check_engine_exportable(model, getattr(model, "path", "model"))
    check_onnx_target(path, bool(config.check_frames))
    from loosefit.body.capsules import avatar_capsules

    avatar = model.avatar()
    capsules, skeleton = avatar_capsules(avatar), skeleton_record(avatar)
    step = (
        EngineStep(model, capsules if config.capsules else None, skeleton, config.waist_blend)
        .cpu()
        .eval()
    )
    meta = export_metadata(
        model,
        path.name,
        config.opset,
        capsules,
        skeleton,
        config.capsules,
        waist_blend=config.waist_blend,
    )

    def check(graph: Path, meta_path: Path) -> dict:  # the reference loop reads the JSON
        return check_frames(model, step, graph, meta_path, config)

    checked = check if config.check_frames else None
    example = example_inputs(model, 2)
    return write_graph_files(
        path,
        step,
        example,
        INPUTS,
        OUTPUTS,
        meta,
        template=model.template,
        opset=config.opset,
        check=checked,
    )


def check_frames(
    model, step: EngineStep, graph: Path, meta_path: Path, config: EngineExportConfig
) -> dict:
    """A procedural dance (``dance:12``) through the reference loop and
    :func:`~loosefit.inference.engine.model.rollout_engine`: the largest difference (m).

    Raises:
        LoosefitInputError: a difference over ``config.tolerance``.
    """
    import onnxruntime as ort

    from loosefit.inference.engine.model import rollout_engine
    from loosefit.inference.engine.runtime import EngineRuntime, rollout_engine_onnx
    from loosefit.motion.motions import load_motion

    motion = load_motion("dance:12", model.avatar(), fps=model.fps, max_frames=config.check_frames)
    runtime = EngineRuntime(graph, threads=1, meta_path=meta_path)
    got = rollout_engine_onnx(runtime, motion)
    want = rollout_engine(model, motion, collide=step)
    worst = float(np.abs(got - want).max())
    if not worst <= config.tolerance:
        raise LoosefitInputError(
            graph,
            "graph",
            f"onnxruntime within {config.tolerance} m of PyTorch over {len(want)} frames",
            f"{worst:.3g} m",
        )
    return {
        "frames": len(want),
        "motion": "dance:12",
        "max_difference_m": worst,
        "onnxruntime": ort.__version__,
    }
