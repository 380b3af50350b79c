"""The learned runtime as one ONNX graph, for a game engine.

One call of the graph is one frame of :func:`~loosefit.inference.rollout.rollout` for B
characters: the motion features of the frame (computed in the graph from the joints),
the dynamic motion encoder's step (its GRU state an explicit input and output), the two
decoders with the UV sampling, and the detail generator. The recurrent state, the
previous garment and the previous root are inputs, and come back as outputs to feed to
the next frame::

    inputs                     shape          outputs                   shape
    joint_rotations            (B, J, 3, 3)   garment                   (B, V, 3)
    root_translation           (B, 3)         next_garment              (B, V, 3)
    start                      (B,) bool      next_hidden               (B, G)
    previous_garment           (B, V, 3)      next_root_rotation        (B, 3, 3)
    hidden                     (B, G)         next_root_translation     (B, 3)
    previous_root_rotation     (B, 3, 3)      latent                    (B, Z)
    previous_root_translation  (B, 3)

``garment`` is what the engine collides and shows; each ``next_X`` is the next frame's
``previous_X`` (``next_hidden``: its ``hidden``); ``latent`` is Z_t.

``start`` marks a character's first frame: its previous garment is then the settled
drape (``rest_state``, kept in the graph), its GRU state zero and its previous root its
own (no velocity); the state inputs are not read. Garments are world positions. The
edge-length stage and collision handling (paper 3.5) are not in the graph: they need the
body's surface, which an engine has in its own collider (docs/use/ENGINE_EXPORT.md).

A JSON file beside the graph (:func:`export_metadata`) says what the inputs mean. The
graph is written by PyTorch's TorchScript-based exporter (``dynamo=False``): it traces
the one-frame step with a free batch size and covers every operator here (the GRU
cell, ``grid_sample``, ``atan2``) at opset 17 without ``onnxscript``, which the
torch.export-based exporter needs.
"""

from __future__ import annotations

import copy
import json
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn

from loosefit.atomic import atomic_path
from loosefit.errors import LoosefitInputError
from loosefit.garment.obj import write_obj
from loosefit.geometry.rotations import axis_angle_to_matrix
from loosefit.inference.protocols import LearnedStages
from loosefit.model.detail import DetailGenerator
from loosefit.model.generative import GarmentGenerativeModel, basis_garment
from loosefit.model.motion_features import (
    JOINT_SETS,
    feature_joints,
    frame_features,
    from_root_frame,
    heading_yaw,
    to_root_frame,
    yaw_matrix,
)
from loosefit.model.uvmap import UVMap

FORMAT = "loosefit-onnx-step/1"  # the JSON's "format"; a change of the graph's inputs bumps it
INPUTS = (
    "joint_rotations",
    "root_translation",
    "start",
    "previous_garment",
    "hidden",
    "previous_root_rotation",
    "previous_root_translation",
)
OUTPUTS = (
    "garment",
    "next_garment",
    "next_hidden",
    "next_root_rotation",
    "next_root_translation",
    "latent",
)
# GenerativeConfig.decoder
SUPPORTED_DECODERS = frozenset({"decomposed", "vertex", "ssdr", "basis"})
STATE = {  # output -> the input it becomes on the next frame
    "next_garment": "previous_garment",
    "next_hidden": "hidden",
    "next_root_rotation": "previous_root_rotation",
    "next_root_translation": "previous_root_translation",
}


@dataclass(frozen=True)
class OnnxExportConfig:
    """How the graph is written."""

    opset: int = 17  # ONNX opset (GridSample needs 16 or later)
    detail: bool = True  # the detail stage in the graph, when the model has one
    check: bool = True  # run one frame in onnxruntime against PyTorch before keeping the file
    tolerance: float = 1e-4  # m: the check's largest allowed difference

    def __post_init__(self) -> None:
        if not (isinstance(self.opset, int) and 16 <= self.opset <= 20):
            raise LoosefitInputError(
                "OnnxExportConfig", "opset", "an integer in 16-20", repr(self.opset)
            )


# -- what can be exported ---------------------------------------------------------------------


def check_exportable(model) -> None:
    """A clear error unless ``model``'s learned stages are the ones the graph is built from.

    Raises:
        LoosefitInputError: naming the stage that is not supported and what is.
    """
    source = getattr(model, "path", "model")
    if not isinstance(model, LearnedStages):
        what = getattr(model, "method", type(model).__name__)
        raise LoosefitInputError(
            source,
            "stage",
            "the paper's motion stage (a motion-stage, detail or packaged checkpoint)",
            f"the '{what}' baseline ({type(model).__name__}), which has no ONNX export",
            hint="export-model exports the motion encoder, the decoders and the detail generator",
        )
    decoder = model.generative.config.decoder
    if decoder not in SUPPORTED_DECODERS:
        raise LoosefitInputError(
            source,
            "stage: generative.decoder",
            f"one of {sorted(SUPPORTED_DECODERS)}",
            repr(decoder),
        )
    if model.detail is not None and not isinstance(model.detail, DetailGenerator):
        raise LoosefitInputError(
            source, "stage: detail", "a DetailGenerator (paper 3.4)", type(model.detail).__name__
        )
    if model.encoder.config.joints not in JOINT_SETS:
        raise LoosefitInputError(
            source,
            "stage: encoder.joints",
            f"one of {list(JOINT_SETS)}",
            repr(model.encoder.config.joints),
        )


# -- the graph --------------------------------------------------------------------------------


class GatherSample(nn.Module):
    """:meth:`UVMap.sample` as gathers: every vertex reads its (at most K) samples from a
    padded (V, K) table, instead of ``index_add_`` (the same sums, in another order).

    Args:
        uv: the garment's UV layout.
    """

    def __init__(self, uv: UVMap) -> None:
        super().__init__()
        vertex, count = uv.sample_vertex, uv.sample_count
        V, N, K = uv.num_vertices, len(vertex), int(count.max())
        order = torch.argsort(vertex, stable=True)
        first = torch.cumsum(count.long(), 0) - count.long()  # (V,) each vertex's first slot
        slot = torch.arange(N) - first[vertex[order]]
        table = torch.full((V, K), N, dtype=torch.long)  # N: a zero sample
        table[vertex[order], slot] = order
        self.register_buffer("grid", uv.sample_grid.clone(), persistent=False)  # (1, 1, N, 2)
        self.register_buffer("table", table, persistent=False)
        self.register_buffer("count", count.float()[None, :, None], persistent=False)

    def forward(self, maps: torch.Tensor) -> torch.Tensor:
        """UV maps (B, C, H, W) to per-vertex values (B, V, C), bilinear."""
        B, C = maps.shape[:2]
        grid = self.grid.expand(B, -1, -1, -1)
        s = nn.functional.grid_sample(
            maps, grid, mode="bilinear", padding_mode="border", align_corners=False
        )
        s = s[:, :, 0].transpose(1, 2)  # (B, N, C)
        s = torch.cat([s, torch.zeros_like(s[:, :1])], 1)  # (B, N + 1, C)
        V, K = self.table.shape
        picked = s[:, self.table.reshape(-1)].reshape(B, V, K, C)
        return picked.sum(2) / self.count


def decode(
    generative: GarmentGenerativeModel, sample: GatherSample, z: torch.Tensor
) -> torch.Tensor:
    """:meth:`GarmentGenerativeModel.decode`'s ``vertices`` (B, V, 3) of codes (B, latent),
    the UV maps read by ``sample``."""
    g, B, V = generative, z.shape[0], generative.num_vertices
    kind = g.config.decoder
    if kind == "decomposed":
        unposed = g.template + g.rec(g.to_static(z)).view(B, V, 3)  # (B, V, 3)
        return unposed + sample(g.dyn(g.to_dynamic(z)))
    if kind == "vertex":
        return sample(g.dec(z))
    if kind == "basis":
        return basis_garment(g, z) + sample(g.dyn(z))
    A = g.bones(z).view(B, -1, 3, 4)  # (B, bones, 3, 4)
    posed = torch.einsum("bkij,vj->bvki", A[..., :3], g.ssdr_rest) + A[:, None, :, :, 3]
    return (g.ssdr_weights[None, :, :, None] * posed).sum(2)


class RuntimeStep(nn.Module):
    """One frame of the learned runtime for B characters (the module docstring's graph).

    Args:
        model: an :class:`~loosefit.inference.animator.AnimationModel`.
        detail: run its detail stage (when it has one).
    """

    def __init__(self, model, detail: bool = True) -> None:
        super().__init__()
        check_exportable(model)
        self.generative, self.encoder = model.generative, model.encoder
        self.detail = model.detail if detail else None
        self.sample = GatherSample(model.generative.uv)
        self.fps, self.floor_height = float(model.fps), float(model.floor_height)
        self.joints = feature_joints(model.joint_names, model.encoder.config.joints)
        self.register_buffer("rest_state", model.rest_state.float().clone(), persistent=False)

    def forward(
        self,
        joint_rotations,
        root_translation,
        start,
        previous_garment,
        hidden,
        previous_root_rotation,
        previous_root_translation,
    ):
        """The inputs and outputs of the module docstring, in that order."""
        root_rotation = joint_rotations[:, 0]  # (B, 3, 3)
        first = start[:, None, None]  # (B, 1, 1)
        before_rot = torch.where(first, root_rotation, previous_root_rotation)
        before_root = torch.where(start[:, None], root_translation, previous_root_translation)
        feats = frame_features(
            joint_rotations,
            root_translation,
            before_rot,
            before_root,
            self.fps,
            self.floor_height,
            joints=self.joints,
        )  # (B, F)
        H = yaw_matrix(heading_yaw(root_rotation))  # (B, 3, 3)
        p = root_translation
        previous = torch.where(first, self.rest_state, to_root_frame(previous_garment, H, p))
        hidden = torch.where(start[:, None], torch.zeros_like(hidden), hidden)
        z, hidden = self.encoder(feats, previous, hidden)
        decoded = from_root_frame(decode(self.generative, self.sample, z), H, p)  # (B, V, 3)
        garment = decoded
        if self.detail is not None:  # as the rollout's later stage: from the world garment
            local = to_root_frame(decoded, H, p)
            garment = from_root_frame(local + self.detail(local, z), H, p)
        return garment, decoded, hidden, root_rotation, root_translation, z


def example_inputs(model, batch: int = 1) -> dict[str, np.ndarray]:
    """Inputs of a first frame (``start`` set) for ``batch`` characters in the rest pose,
    standing on the floor at the origin: numpy arrays by input name."""
    J, V, G = len(model.joint_names), model.template.num_vertices, model.encoder.config.gru
    rot = np.broadcast_to(np.eye(3, dtype=np.float32), (batch, J, 3, 3)).copy()
    root = np.tile(np.array([0.0, 0.0, model.floor_height], np.float32), (batch, 1))
    return {
        "joint_rotations": rot,
        "root_translation": root,
        "start": np.ones(batch, bool),
        "previous_garment": np.zeros((batch, V, 3), np.float32),
        "hidden": np.zeros((batch, G), np.float32),
        "previous_root_rotation": rot[:, 0].copy(),
        "previous_root_translation": root.copy(),
    }


# -- the JSON beside it -----------------------------------------------------------------------


def graph_header(model, format: str, onnx_name: str, opset: int) -> dict:
    """The JSON's first fields, the same for every exported graph: its format, files,
    conventions, frame rate and skeleton."""
    return {
        "format": format,
        "onnx": onnx_name,
        "mesh": str(Path(onnx_name).with_suffix(".obj")),
        "opset": opset,
        "checkpoint": str(model.path),
        "conventions": "metres, seconds, radians; world right-handed, Z up; at rest the "
        "avatar faces -Y, its left hand towards +X (loosefit.types)",
        "frame_rate": float(model.fps),
        "floor_height": float(model.floor_height),
        "joint_names": list(model.joint_names),
        "joint_order": "joint_rotations[:, j] is the local rotation (parent to joint, a "
        "rotation matrix acting on column vectors) of joint_names[j]; joint 0 is the root "
        "and its rotation is world",
        "vertex_count": int(model.template.num_vertices),
        "face_count": int(len(model.template.faces)),
    }


def export_metadata(model, onnx_name: str, detail: bool, opset: int) -> dict:
    """What the graph's inputs and outputs mean: the JSON written beside it."""
    J, V = len(model.joint_names), model.template.num_vertices
    G, Z = model.encoder.config.gru, model.encoder.latent
    joints = feature_joints(model.joint_names, model.encoder.config.joints)
    K = len(joints)
    rc = model.rollout_config
    f32 = "float32"

    def io(shape, dtype, meaning):
        return {"shape": shape, "dtype": dtype, "meaning": meaning}

    inputs = {
        "joint_rotations": io(["B", J, 3, 3], f32, "this frame's local joint rotations"),
        "root_translation": io(["B", 3], f32, "this frame's root joint position, world"),
        "start": io(
            ["B"],
            "bool",
            "true on a character's first frame: the state inputs "
            "are then not read (settled drape, zero GRU state, no velocity)",
        ),
        "previous_garment": io(["B", V, 3], f32, "next_garment of the frame before"),
        "hidden": io(["B", G], f32, "next_hidden of the frame before"),
        "previous_root_rotation": io(
            ["B", 3, 3],
            f32,
            "next_root_rotation of the frame before (the root's joint_rotations[:, 0])",
        ),
        "previous_root_translation": io(["B", 3], f32, "next_root_translation of the frame before"),
    }
    state = dict(STATE)
    if not model.encoder.config.previous_state:  # the "w/o ps" ablation: no E_s, no input
        del inputs["previous_garment"], state["next_garment"]
    return {
        **graph_header(model, FORMAT, onnx_name, opset),
        "hidden_size": G,
        "latent_size": Z,
        "stages": {
            "in_graph": ["motion features", "motion encoder step (GRU)", "decoders", "UV sampling"]
            + (["detail generator"] if detail else []),
            "not_in_graph": [
                "edge lengths (loosefit.inference.stages.lengths.LengthRestorer)",
                "collision handling (paper 3.5): the engine's collider",
            ],
        },
        "inputs": inputs,
        "outputs": {
            "garment": io(
                ["B", V, 3],
                f32,
                "the garment's vertices, world: give these to "
                "the collider and the renderer" + ("" if detail else " (no detail stage)"),
            ),
            "next_garment": io(
                ["B", V, 3],
                f32,
                "the decoders' garment, world: the next "
                "frame's previous_garment (not the collided garment: the "
                "encoder was trained on its own output)",
            ),
            "next_hidden": io(["B", G], f32, "the GRU state: the next frame's hidden"),
            "next_root_rotation": io(["B", 3, 3], f32, "the next frame's previous_root_rotation"),
            "next_root_translation": io(
                ["B", 3], f32, "the next frame's previous_root_translation"
            ),
            "latent": io(["B", Z], f32, "Z_t, the motion encoder's code"),
        },
        "state": state,
        "motion_features": {
            "where": "computed in the graph from joint_rotations, root_translation and the "
            "previous root (loosefit.model.motion_features.frame_features), normalised by "
            "the training set's mean and standard deviation (in the graph)",
            "layout": [
                {
                    "name": "joint rotations, 6D (first two matrix columns)",
                    "joints": [model.joint_names[j] for j in joints],
                    "size": 6 * K,
                },
                {"name": "root rotation relative to its heading, 6D", "size": 6},
                {"name": "root velocity in the heading frame (m/s)", "size": 3},
                {"name": "heading turn rate (rad/s)", "size": 1},
                {"name": "root height above floor_height (m)", "size": 1},
            ],
            "size": int(model.encoder.num_features),
            "heading": "yaw about +Z of the root's forward direction (-Y at rest): "
            "atan2(f_x, -f_y) with f = -R_root[:, 1]",
        },
        "start_of_motion": {
            "warm_frames": int(rc.warm_frames),
            "blend_seconds": float(rc.blend_seconds),
            "meaning": "as trained: the avatar stands in the rest pose (identity local "
            "rotations, the root at floor_height where the motion starts, turned to its "
            "heading) for warm_frames frames, the first with start=true, then blends into "
            "the motion's first frame over blend_seconds (local rotations slerped, the root "
            "lerped, smoothstep timing): loosefit.motion.chain.preroll",
        },
        "max_distance": float(rc.max_distance),
        "divergence": "a vertex farther than max_distance m from the root, or NaN, means the "
        "rollout has diverged",
    }


# -- writing ----------------------------------------------------------------------------------


def needs_package(module: str, source: str = "export-model") -> None:
    """A clear error, naming ``source`` and the ``onnx`` extra, unless ``module`` imports.

    Raises:
        LoosefitInputError: ``module`` (``onnx``, ``onnxruntime``) is not installed.
    """
    try:
        __import__(module)
    except ImportError:
        raise LoosefitInputError(
            source,
            "<dependencies>",
            f"the {module} package (pip install 'loosefit[onnx]')",
            "not installed",
        ) from None


def export_onnx(model, path: str | Path, config: OnnxExportConfig | None = None) -> list[Path]:
    """Write ``model``'s learned runtime as ONNX at ``path``, its JSON beside it (``path``
    with ``.json``) and the garment's mesh (``.obj``: the rest shape, faces and UVs, its
    vertices in the graph's order), all three or none.

    Args:
        model: an :class:`~loosefit.inference.animator.AnimationModel` (on any device; the
            graph is traced on the CPU).
        path: the ``.onnx`` file to write.
        config: the opset, the detail stage, the check.

    Returns:
        The three paths written.

    Raises:
        LoosefitInputError: a stage the graph does not support, a path that is not
            ``.onnx``, a missing ``onnx``/``onnxruntime`` package, or a graph whose first
            frame differs from PyTorch's by more than ``config.tolerance``.
    """
    config = config or OnnxExportConfig()
    path = Path(path)
    check_exportable(model)
    check_onnx_target(path, config.check)
    detail = config.detail and model.detail is not None
    step = copy.deepcopy(RuntimeStep(model, detail)).cpu().eval()  # the model stays put
    meta = export_metadata(model, path.name, detail, config.opset)

    def check(graph: Path, _meta_path: Path) -> dict:
        return check_first_frame(step, graph, model, config.tolerance)

    checked = check if config.check else None
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


def check_onnx_target(path: Path, checked: bool) -> None:
    """Refuse an export path not ending in ``.onnx``, or a missing ``onnx`` (or, when the
    graph is to be ``checked``, ``onnxruntime``) package.

    Raises:
        LoosefitInputError: naming the path or the package.
    """
    if path.suffix != ".onnx":
        raise LoosefitInputError(path, "<file>", "a path ending in .onnx", repr(path.suffix))
    needs_package("onnx")
    if checked:
        needs_package("onnxruntime")


def write_graph_files(
    path: Path,
    step: nn.Module,
    example: dict[str, np.ndarray],
    inputs,
    outputs,
    meta: dict,
    *,
    template,
    opset: int,
    check: Callable[[Path, Path], dict] | None = None,
) -> list[Path]:
    """Trace ``step`` into ``path`` (``.onnx``) with ``meta`` in its metadata, the JSON beside
    it and the garment ``template``'s mesh (``.obj``), all three or none. ``check(graph,
    json)``, run on the written files before they are kept, may raise to keep none; what it
    returns is the JSON's ``check``.

    Returns:
        The three paths written.
    """
    example = {k: torch.from_numpy(v) for k, v in example.items()}
    json_path, obj_path = path.with_suffix(".json"), path.with_suffix(".obj")
    with (
        atomic_path(path) as tmp,
        atomic_path(json_path) as tmp_json,
        atomic_path(obj_path) as tmp_obj,
    ):
        t = template
        write_obj(tmp_obj, t.vertices, t.faces, t.uvs, t.face_uvs)
        trace_graph(step, tuple(example[k] for k in inputs), str(tmp), inputs, outputs, opset)
        _set_metadata(tmp, meta)
        if check is not None:
            tmp_json.write_text(json.dumps(meta))  # a check may read it beside the graph
            meta["check"] = check(tmp, tmp_json)
        tmp_json.write_text(json.dumps(meta, indent=1) + "\n")
    return [path, json_path, obj_path]


def trace_graph(module: nn.Module, example: tuple, target, inputs, outputs, opset: int) -> None:
    """``module`` (on the CPU, in eval mode) traced on ``example`` into an ONNX graph written
    to ``target`` (a path or a binary file object), every input and output's first axis
    (the batch) free."""
    with torch.no_grad(), warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the legacy exporter's deprecation, trace notes
        torch.onnx.export(
            module,
            example,
            target,
            dynamo=False,
            opset_version=opset,
            input_names=list(inputs),
            output_names=list(outputs),
            dynamic_axes={k: {0: "B"} for k in (*inputs, *outputs)},
        )


def _set_metadata(path: Path, meta: dict) -> None:
    """The JSON's text in the graph's metadata too (``loosefit``), for a single-file engine."""
    import onnx

    proto = onnx.load(str(path))
    onnx.checker.check_model(proto)
    entry = proto.metadata_props.add()
    entry.key, entry.value = "loosefit", json.dumps(meta)
    proto.doc_string = "loosefit runtime step; see the 'loosefit' metadata"
    onnx.save(proto, str(path))


def check_first_frame(step: RuntimeStep, path: Path, model, tolerance: float) -> dict:
    """Two frames (the rest pose, then a bent one) through onnxruntime and PyTorch: the
    largest difference (m) of the garments, recorded in the JSON.

    Raises:
        LoosefitInputError: a difference over ``tolerance``.
    """
    import onnxruntime as ort

    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    feed = example_inputs(model, 1)
    names = [i.name for i in session.get_inputs()]  # an input the graph does not read is not in it
    worst = 0.0
    for _ in range(2):
        got = dict(zip(OUTPUTS, session.run(None, {k: feed[k] for k in names}), strict=True))
        with torch.no_grad():
            want = step(*(torch.from_numpy(feed[k]) for k in INPUTS))
        worst = max(worst, float(np.abs(got["garment"] - want[0].numpy()).max()))
        feed = {**feed, **{STATE[k]: got[k] for k in STATE}, "start": np.zeros(1, bool)}
        # every joint but the root turned 0.3 rad about x
        bent = axis_angle_to_matrix(np.array([0.3, 0.0, 0.0])) @ feed["joint_rotations"][0, 1:]
        feed["joint_rotations"] = feed["joint_rotations"].copy()
        feed["joint_rotations"][0, 1:] = bent
        feed["root_translation"] = feed["root_translation"] + np.float32([0.01, 0.0, 0.0])
    if not worst <= tolerance:
        raise LoosefitInputError(
            path,
            "graph",
            f"onnxruntime within {tolerance} m of PyTorch on two frames",
            f"{worst:.3g} m",
        )
    return {"frames": 2, "max_difference_m": worst, "onnxruntime": ort.__version__}
