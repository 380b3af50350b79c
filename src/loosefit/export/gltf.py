"""Binary glTF 2.0 (``.glb``), written directly (the format is a JSON header and one binary
buffer, both specified in full by Khronos).

glTF is Y up and in metres: every position is turned from loosefit's Z up. A mesh with a
rig (the body) is a skinned mesh: its joints are nodes named as the capture's joints, in
its order, each with its bind pose as its rest transform; a ``skin`` holds their inverse
bind matrices, and one animation channel per joint gives its translation and rotation on
every frame. The body's seven influences a vertex go in two sets (``JOINTS_0``/
``WEIGHTS_0``, the four largest, and ``JOINTS_1``/``WEIGHTS_1``); readers that take one set
(three.js) drop the smallest three. A mesh without a rig (the garment) is one morph target
a frame (positions relative to frame 0) and a ``weights`` animation that turns frame t's
target fully on at time t / fps: one mesh that any glTF player animates, interpolating
linearly between frames. The weights are a sparse accessor (T values, not T x T). Vertices
are split where a vertex has several UVs (the glTF way); ``extras.loosefit_vertex`` on
the mesh gives each written vertex's index in the original mesh.

The file is streamed: the JSON first (the layout is known from the shapes), then the
binary chunk a frame at a time, so a long sequence is never copied whole.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np

from loosefit.atomic import atomic_path
from loosefit.export.meshes import (
    Z_TO_Y_UP,
    AnimatedMesh,
    ExportConfig,
    Skin,
    check_meshes,
    skin_to_write,
)
from loosefit.export.usd import continuous_quaternions

FLOAT, UINT, USHORT = 5126, 5125, 5123
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963


@dataclass
class _Layout:
    """The binary chunk as pieces written in order, and the JSON that points into it."""

    pieces: list[tuple[int, Callable[[], Iterator[bytes]]]] = field(default_factory=list)
    views: list[dict] = field(default_factory=list)
    accessors: list[dict] = field(default_factory=list)
    size: int = 0

    def view(self, length: int, chunks: Callable[[], Iterator[bytes]], target=None) -> int:
        """A buffer view of ``length`` bytes that ``chunks()`` yields when written."""
        assert length % 4 == 0  # every element here is 4-byte aligned
        self.views.append({"buffer": 0, "byteOffset": self.size, "byteLength": length})
        if target is not None:
            self.views[-1]["target"] = target
        self.pieces.append((length, chunks))
        self.size += length
        return len(self.views) - 1

    def array(self, a: np.ndarray, kind: str, ctype: int = FLOAT, target=None, bounds=False):
        """An accessor of a whole array (written as it is, little-endian)."""
        dtype = {FLOAT: "<f4", UINT: "<u4", USHORT: "<u2"}[ctype]
        data = np.ascontiguousarray(a, dtype)
        view = self.view(data.nbytes, lambda: iter([data.tobytes()]), target)
        return self.accessor(view, ctype, len(data), kind, data if bounds else None)

    def accessor(self, view, ctype, count, kind, bounds_of=None, bounds=None) -> int:
        acc = {"componentType": ctype, "count": int(count), "type": kind}
        if view is not None:
            acc["bufferView"] = view
        if bounds_of is not None:
            flat = bounds_of.reshape(len(bounds_of), -1)
            bounds = (flat.min(0), flat.max(0))
        if bounds is not None:
            acc["min"], acc["max"] = ([float(x) for x in b] for b in bounds)
        self.accessors.append(acc)
        return len(self.accessors) - 1


def _trs(m: np.ndarray) -> dict:
    """A rigid (4, 4) transform as glTF's ``translation`` and ``rotation`` (x, y, z, w)."""
    w, x, y, z = continuous_quaternions(m[None, None, :3, :3])[0, 0].tolist()
    return {"translation": m[:3, 3].tolist(), "rotation": [x, y, z, w]}


class GltfVertices(NamedTuple):
    """A mesh's vertices as glTF writes them (:func:`split_uvs`)."""

    source: np.ndarray  # (N,) the original vertex of each written one
    faces: np.ndarray  # (F, 3) into the written vertices
    uvs: np.ndarray | None  # (N, 2) V flipped (glTF's origin is the top left); None: none


def split_uvs(m: AnimatedMesh) -> GltfVertices:
    """glTF's vertices: one per distinct (vertex, UV) pair.

    Returns:
        :class:`GltfVertices`: source (N,) the original vertex of each written one, faces
        (F, 3) into them, and their (N, 2) UVs (V flipped: glTF's origin is the top left),
        or None.
    """
    if m.uvs is None:
        return GltfVertices(np.arange(m.vertices.shape[1]), m.faces, None)
    pairs = np.stack([m.faces.ravel(), m.face_uvs.ravel()], 1)  # (3F, 2)
    unique, inverse = np.unique(pairs, axis=0, return_inverse=True)
    uv = m.uvs[unique[:, 1]] * np.float32([1, -1]) + np.float32([0, 1])
    return GltfVertices(unique[:, 0], inverse.reshape(-1, 3), uv)


def _skin_attributes(skin: Skin) -> dict:
    """(Vb, 8) joints and weights, largest weight first, as two glTF sets."""
    order = np.argsort(-skin.weights, axis=1, kind="stable")
    w = np.take_along_axis(skin.weights, order, 1)
    j = np.take_along_axis(skin.indices, order, 1)
    pad = 8 - w.shape[1]
    w = np.pad(w, ((0, 0), (0, pad)))
    j = np.where(w > 0, np.pad(j, ((0, 0), (0, pad))), 0)
    return {"joints": j, "weights": w / w.sum(1, keepdims=True)}


def export_gltf(
    path: Path, meshes: list[AnimatedMesh], fps: float, config: ExportConfig | None = None
) -> list[Path]:
    """A ``.glb``: rigged meshes skinned, the others as one morph target a frame."""
    config = config or ExportConfig()
    T = check_meshes(meshes, fps, path)
    A = Z_TO_Y_UP.astype(np.float32)
    lay = _Layout()
    nodes: list[dict] = []
    gmeshes: list[dict] = []
    skins: list[dict] = []
    channels: list[dict] = []
    samplers: list[dict] = []
    times = lay.array(np.arange(T, dtype=np.float32) / fps, "SCALAR", bounds=True)
    times_acc = lay.accessors[times]
    times_acc["min"], times_acc["max"] = [0.0], [float((T - 1) / fps)]

    def sampler(output: int) -> int:
        samplers.append({"input": times, "output": output, "interpolation": "LINEAR"})
        return len(samplers) - 1

    for m in meshes:
        source, faces, uv = split_uvs(m)
        skin = skin_to_write(m, config, path)
        attributes = {}
        prim: dict = {"attributes": attributes, "mode": 4}
        prim["indices"] = lay.array(faces.ravel(), "SCALAR", UINT, ELEMENT_ARRAY_BUFFER)
        if uv is not None:
            attributes["TEXCOORD_0"] = lay.array(uv, "VEC2", target=ARRAY_BUFFER)
        mesh = {"name": m.name, "primitives": [prim], "extras": {}}
        if not np.array_equal(source, np.arange(m.vertices.shape[1])):
            mesh["extras"]["loosefit_vertex"] = source.tolist()
        node = {"name": m.name, "mesh": len(gmeshes)}
        if skin is not None:
            skin = skin.transformed(Z_TO_Y_UP)
            rest = skin.rest_vertices[source].astype(np.float32)
            attributes["POSITION"] = lay.array(rest, "VEC3", target=ARRAY_BUFFER, bounds=True)
            sk = _skin_attributes(skin)
            for s in range(2):
                attributes[f"JOINTS_{s}"] = lay.array(
                    sk["joints"][source, 4 * s : 4 * s + 4], "VEC4", USHORT, ARRAY_BUFFER
                )
                attributes[f"WEIGHTS_{s}"] = lay.array(
                    sk["weights"][source, 4 * s : 4 * s + 4], "VEC4", target=ARRAY_BUFFER
                )
            first = len(nodes) + 1  # the joints follow the mesh's node
            local_bind = skin.local_bind_poses()
            joints = []
            for j, name in enumerate(skin.joint_names):
                kids = [first + c for c in np.nonzero(skin.parents == j)[0]]
                joints.append({"name": name, **_trs(local_bind[j])})
                if kids:
                    joints[-1]["children"] = [int(k) for k in kids]
            inverse_bind = np.linalg.inv(skin.bind_poses).transpose(0, 2, 1)  # column-major
            skins.append(
                {
                    "name": f"{m.name}_rig",
                    "joints": list(range(first, first + len(joints))),
                    "skeleton": first,
                    "inverseBindMatrices": lay.array(inverse_bind.reshape(-1, 16), "MAT4"),
                }
            )
            node["skin"] = len(skins) - 1
            local = skin.local_poses()  # (T, J, 4, 4)
            quats = continuous_quaternions(local[..., :3, :3])[..., [1, 2, 3, 0]]  # x, y, z, w
            for j in range(len(joints)):
                t_out = lay.array(local[:, j, :3, 3], "VEC3")
                r_out = lay.array(quats[:, j], "VEC4")
                for out, kind in ((t_out, "translation"), (r_out, "rotation")):
                    channels.append(
                        {"sampler": sampler(out), "target": {"node": first + j, "path": kind}}
                    )
            nodes.append(node)
            roots = [first + j for j in range(len(joints)) if skin.parents[j] < 0]
            nodes.extend(joints)
            node["_roots"] = roots
        else:
            base = m.vertices[0][source] @ A.T  # (N, 3)
            attributes["POSITION"] = lay.array(base, "VEC3", target=ARRAY_BUFFER, bounds=True)
            prim["targets"], weights = _morph_targets(lay, m, source, base, A)
            mesh["weights"] = [1.0] + [0.0] * (T - 1)
            mesh["extras"]["targetNames"] = [f"frame_{t:06d}" for t in range(T)]
            channels.append(
                {"sampler": sampler(weights), "target": {"node": len(nodes), "path": "weights"}}
            )
            nodes.append(node)
        if not mesh["extras"]:
            del mesh["extras"]
        gmeshes.append(mesh)

    scene_nodes = []
    for i, n in enumerate(nodes):
        if "mesh" in n:
            scene_nodes.append(i)
            scene_nodes.extend(n.pop("_roots", []))
    doc = {
        "asset": {"version": "2.0", "generator": "loosefit"},
        "scene": 0,
        "scenes": [{"name": "loosefit", "nodes": scene_nodes}],
        "nodes": nodes,
        "meshes": gmeshes,
        "accessors": lay.accessors,
        "bufferViews": lay.views,
        "buffers": [{"byteLength": lay.size}],
        "animations": [{"name": "loosefit", "channels": channels, "samplers": samplers}],
    }
    if skins:
        doc["skins"] = skins
    _write_glb(path, doc, lay)
    return [path]


def _morph_targets(
    lay: _Layout, m: AnimatedMesh, source: np.ndarray, base: np.ndarray, A: np.ndarray
) -> tuple[list[dict], int]:
    """Every frame of ``m`` as a morph target on ``base`` (N, 3), its delta written a frame
    at a time; and the accessor of the ``weights`` animation that turns frame t on at t
    (sparse: T ones on the diagonal of T x T)."""
    T = len(m.vertices)
    targets = []
    for t in range(T):
        delta_view = lay.view(
            12 * len(source),
            lambda t=t: iter([(m.vertices[t][source] @ A.T - base).astype("<f4").tobytes()]),
            ARRAY_BUFFER,
        )
        d = m.vertices[t][source] @ A.T - base  # its bounds, for the accessor
        targets.append({"POSITION": lay.accessor(delta_view, FLOAT, len(source), "VEC3", d)})
    diag = np.arange(T, dtype=np.uint64) * (T + 1)
    ind = lay.view(4 * T, lambda: iter([diag.astype("<u4").tobytes()]))
    val = lay.view(4 * T, lambda: iter([np.ones(T, "<f4").tobytes()]))
    weights = lay.accessor(None, FLOAT, T * T, "SCALAR")
    lay.accessors[weights]["sparse"] = {
        "count": T,
        "indices": {"bufferView": ind, "componentType": UINT},
        "values": {"bufferView": val},
    }
    return targets, weights


def _write_glb(path: Path, doc: dict, lay: _Layout) -> None:
    """The binary glTF: header, JSON chunk, then the binary chunk streamed piece by piece."""
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    total = 12 + 8 + len(text) + 8 + lay.size
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        fh.write(struct.pack("<4sII", b"glTF", 2, total))
        fh.write(struct.pack("<I4s", len(text), b"JSON") + text)
        fh.write(struct.pack("<I4s", lay.size, b"BIN\0"))
        for length, chunks in lay.pieces:
            written = 0
            for chunk in chunks():
                fh.write(chunk)
                written += len(chunk)
            assert written == length  # the layout promised it
