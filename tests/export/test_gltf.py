"""glTF: one written vertex per (vertex, UV) pair, and a .glb read with a reader written from
the specification: the container, the frames as morph targets, the weights that play them."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.export.gltf import export_gltf, split_uvs
from loosefit.export.meshes import AnimatedMesh


def _quad(T: int = 3) -> AnimatedMesh:
    """Two triangles on four vertices, their UVs cut along the diagonal: five UV corners."""
    v = np.array([[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], np.float32)
    moves = v[None] + np.arange(T, dtype=np.float32)[:, None, None] * np.float32([0.1, 0.2, 0.3])
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    uvs = np.array([[0, 0], [1, 0], [1, 1], [0.9, 1], [0, 1]], np.float32)
    return AnimatedMesh("garment", faces, moves, uvs, np.array([[0, 1, 2], [0, 3, 4]]))


def test_a_vertex_is_written_once_per_uv_it_has():
    m = _quad()
    source, faces, uv = split_uvs(m)
    # vertex 2 has two UVs (1, 1) and (0.9, 1): written twice; the others once
    assert sorted(source.tolist()) == [0, 1, 2, 2, 3]
    np.testing.assert_array_equal(source[faces], m.faces)  # the same triangles
    corner_uv = uv[faces.ravel()]  # V flipped: glTF's origin is the top left
    want = m.uvs[m.face_uvs.ravel()] * [1, -1] + [0, 1]
    np.testing.assert_allclose(corner_uv, want)
    plain = AnimatedMesh("body", m.faces, m.vertices)
    source, faces, uv = split_uvs(plain)
    assert source.tolist() == [0, 1, 2, 3] and uv is None and faces is plain.faces


def _read_glb(path):
    raw = path.read_bytes()
    magic, version, total = struct.unpack_from("<4sII", raw)
    assert (magic, version, total) == (b"glTF", 2, len(raw))
    n, kind = struct.unpack_from("<I4s", raw, 12)
    assert kind == b"JSON" and n % 4 == 0
    doc = json.loads(raw[20 : 20 + n])
    m, kind = struct.unpack_from("<I4s", raw, 20 + n)
    assert kind == b"BIN\0" and m == doc["buffers"][0]["byteLength"] and 28 + n + m == len(raw)
    return doc, raw[28 + n :]


def _dense(doc, blob, i) -> np.ndarray:
    a = doc["accessors"][i]
    width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3}[a["type"]]
    dtype = {5126: "<f4", 5125: "<u4"}[a["componentType"]]
    out = np.zeros((a["count"], width), dtype)
    if "bufferView" in a:
        view = doc["bufferViews"][a["bufferView"]]
        out = np.frombuffer(blob, dtype, a["count"] * width, view["byteOffset"]).reshape(-1, width)
    if "sparse" in a:
        s, out = a["sparse"], out.copy()
        idx = doc["bufferViews"][s["indices"]["bufferView"]]
        val = doc["bufferViews"][s["values"]["bufferView"]]
        at = np.frombuffer(blob, "<u4", s["count"], idx["byteOffset"])
        out[at] = np.frombuffer(blob, dtype, s["count"] * width, val["byteOffset"]).reshape(
            -1, width
        )
    return out


def test_every_frame_is_a_morph_target_played_one_at_a_time(tmp_path):
    m = _quad(T=3)
    path = tmp_path / "g.glb"
    assert export_gltf(path, [m], 20.0) == [path]
    doc, blob = _read_glb(path)
    assert doc["asset"]["version"] == "2.0" and doc["meshes"][0]["name"] == "garment"
    prim = doc["meshes"][0]["primitives"][0]
    source = np.array(doc["meshes"][0]["extras"]["loosefit_vertex"])
    base = _dense(doc, blob, prim["attributes"]["POSITION"])
    faces = _dense(doc, blob, prim["indices"]).reshape(-1, 3)
    np.testing.assert_array_equal(source[faces], m.faces)
    y_up = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])  # glTF is Y up
    (animation,) = doc["animations"]
    (channel,) = animation["channels"]
    sampler = animation["samplers"][channel["sampler"]]
    times = _dense(doc, blob, sampler["input"])[:, 0]
    np.testing.assert_allclose(times, [0.0, 0.05, 0.1])
    weights = _dense(doc, blob, sampler["output"]).reshape(3, 3)  # a row per key, a target each
    np.testing.assert_array_equal(weights, np.eye(3))
    for t, target in enumerate(prim["targets"]):  # frame t: the base plus its target
        got = base + _dense(doc, blob, target["POSITION"])
        np.testing.assert_allclose(got, m.vertices[t][source] @ y_up.T, atol=1e-6)


def test_nothing_to_write_is_refused_and_leaves_no_file(tmp_path):
    with pytest.raises(LoosefitInputError, match=r"g\.glb: field 'meshes': expected at least one"):
        export_gltf(tmp_path / "g.glb", [], 20.0)
    with pytest.raises(LoosefitInputError, match=r"field 'fps'"):
        export_gltf(tmp_path / "g.glb", [_quad()], -1.0)
    assert not list(tmp_path.iterdir())
