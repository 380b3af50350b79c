"""A character's own glTF with an animated mesh added, everything of theirs untouched.

The mesh is written as loosefit's glTF exporter writes a garment (one morph target a
frame, :func:`loosefit.export.gltf.export_gltf`), then joined to the character's
document: its nodes, meshes, accessors and buffer views appended after theirs (indices
moved past theirs), its weights channel added to the character's animation on the
character's own times, its node to the character's scene. Their buffers are packed into
the one binary chunk of a ``.glb`` (byte offsets moved, bytes unchanged); images and
buffers stored in files beside theirs are read in and packed too.
"""

from __future__ import annotations

import json
import struct
import tempfile
from pathlib import Path

import numpy as np

from loosefit.atomic import atomic_path
from loosefit.motion.gltf_file import read_document


def _pad(data: bytearray, to: int = 4) -> None:
    while len(data) % to:
        data.append(0)


def add_animated_mesh(character, mesh, path: Path) -> Path:
    """Write ``character``'s file with ``mesh`` (an
    :class:`~loosefit.export.meshes.AnimatedMesh`, Z up: turned to glTF's Y up) animated
    on its frames' times, as the ``.glb`` ``path``."""
    from loosefit.export.gltf import export_gltf

    base = read_document(character.path)
    with tempfile.TemporaryDirectory() as tmp:
        extra = read_document(export_gltf(Path(tmp) / "mesh.glb", [mesh], 30.0)[0])
    doc = json.loads(json.dumps(base.gltf))  # a copy
    data = bytearray()
    starts = []
    for b in base.buffers:  # theirs, packed
        _pad(data)
        starts.append(len(data))
        data += b
    for view in doc.get("bufferViews", []):
        view["byteOffset"] = starts[view.get("buffer", 0)] + view.get("byteOffset", 0)
        view["buffer"] = 0
    _pad(data)
    extra_start = len(data)
    data += extra.buffers[0]
    n_view, n_acc = len(doc.get("bufferViews", [])), len(doc.get("accessors", []))
    n_mesh, n_node = len(doc.get("meshes", [])), len(doc.get("nodes", []))
    for view in extra.gltf["bufferViews"]:
        doc.setdefault("bufferViews", []).append(
            {**view, "buffer": 0, "byteOffset": extra_start + view.get("byteOffset", 0)}
        )
    for acc in extra.gltf["accessors"]:
        acc = json.loads(json.dumps(acc))
        if "bufferView" in acc:
            acc["bufferView"] += n_view
        for part in ("indices", "values"):
            if part in acc.get("sparse", {}):
                acc["sparse"][part]["bufferView"] += n_view
        doc.setdefault("accessors", []).append(acc)
    for m in extra.gltf["meshes"]:
        for prim in m["primitives"]:
            prim["attributes"] = {k: v + n_acc for k, v in prim["attributes"].items()}
            prim["indices"] += n_acc
            prim["targets"] = [{k: v + n_acc for k, v in t.items()} for t in prim["targets"]]
        doc.setdefault("meshes", []).append(m)
    node = dict(extra.gltf["nodes"][0], mesh=n_mesh)
    doc.setdefault("nodes", []).append(node)
    scene = doc.get("scene", 0)
    doc.setdefault("scenes", [{"nodes": []}])[scene].setdefault("nodes", []).append(n_node)

    # the weights on the character's own timeline
    times = np.asarray(character.times[: mesh.num_frames], "<f4")  # the frames dressed
    _pad(data)
    doc["bufferViews"].append({"buffer": 0, "byteOffset": len(data), "byteLength": times.nbytes})
    data += times.tobytes()
    doc["accessors"].append(
        {
            "bufferView": len(doc["bufferViews"]) - 1,
            "componentType": 5126,
            "count": len(times),
            "type": "SCALAR",
            "min": [float(times.min())],
            "max": [float(times.max())],
        }
    )
    sampler = extra.gltf["animations"][0]["samplers"][0]
    anim = doc["animations"][character.animation]
    anim["samplers"].append(
        {
            "input": len(doc["accessors"]) - 1,
            "output": sampler["output"] + n_acc,
            "interpolation": "LINEAR",
        }
    )
    anim["channels"].append(
        {"sampler": len(anim["samplers"]) - 1, "target": {"node": n_node, "path": "weights"}}
    )
    for image in doc.get("images", []):  # files beside theirs: packed in
        uri = image.get("uri")
        if uri and not uri.startswith("data:"):
            raw = (Path(character.path).parent / uri).read_bytes()
            _pad(data)
            doc["bufferViews"].append(
                {"buffer": 0, "byteOffset": len(data), "byteLength": len(raw)}
            )
            data += raw
            image.pop("uri")
            image["bufferView"] = len(doc["bufferViews"]) - 1
            png = uri.lower().endswith("png")
            image.setdefault("mimeType", "image/png" if png else "image/jpeg")
    _pad(data)
    doc["buffers"] = [{"byteLength": len(data)}]
    doc.setdefault("asset", {"version": "2.0"})
    return write_glb(path, doc, bytes(data))


def write_glb(path: Path, doc: dict, data: bytes) -> Path:
    """A ``.glb``: header, JSON chunk, binary chunk (written atomically)."""
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    total = 12 + 8 + len(text) + 8 + len(data)
    with atomic_path(Path(path)) as tmp, open(tmp, "wb") as fh:
        fh.write(struct.pack("<4sII", b"glTF", 2, total))
        fh.write(struct.pack("<I4s", len(text), b"JSON") + text)
        fh.write(struct.pack("<I4s", len(data), b"BIN\0") + data)
    return Path(path)
