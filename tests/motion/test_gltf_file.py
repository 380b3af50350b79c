import base64
import json
import struct

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.motion.gltf_file import GltfDocument, read_accessor, read_document

ASSET = {"version": "2.0"}


def _doc(accessors, views, data: bytes, tmp_path) -> GltfDocument:
    gltf = {"asset": ASSET, "accessors": accessors, "bufferViews": views}
    gltf["buffers"] = [{"byteLength": len(data)}]
    return GltfDocument(tmp_path / "t.gltf", gltf, [data])


def _glb(gltf: dict, binary: bytes) -> bytes:
    text = json.dumps(gltf).encode()
    text += b" " * (-len(text) % 4)
    binary += b"\0" * (-len(binary) % 4)
    chunks = struct.pack("<II", len(text), 0x4E4F534A) + text
    chunks += struct.pack("<II", len(binary), 0x004E4942) + binary
    return struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks


def test_a_gltf_with_an_embedded_buffer_and_one_beside_it(tmp_path):
    a, b = b"\x01\x02\x03\x04", b"\x05\x06"
    (tmp_path / "my data.bin").write_bytes(b)
    uri = "data:application/octet-stream;base64," + base64.b64encode(a).decode()
    gltf = {
        "asset": ASSET,
        "buffers": [{"uri": uri, "byteLength": 4}, {"uri": "my%20data.bin", "byteLength": 2}],
    }
    path = tmp_path / "scene.gltf"
    path.write_text(json.dumps(gltf))
    doc = read_document(path)
    assert doc.path == path and doc.buffers == [a, b]
    assert doc.gltf["asset"]["version"] == "2.0"


def test_a_glb_reads_its_json_and_binary_chunks(tmp_path):
    floats = np.arange(6, dtype="<f4")
    gltf = {
        "asset": ASSET,
        "buffers": [{"byteLength": 24}],
        "bufferViews": [{"buffer": 0, "byteLength": 24}],
        "accessors": [{"bufferView": 0, "count": 2, "componentType": 5126, "type": "VEC3"}],
    }
    path = tmp_path / "scene.glb"
    path.write_bytes(_glb(gltf, floats.tobytes()))
    doc = read_document(path)
    np.testing.assert_array_equal(read_accessor(doc, 0, "x"), [[0, 1, 2], [3, 4, 5]])


@pytest.mark.parametrize(
    ("name", "content", "field"),
    [
        ("a.glb", b"glTF" + struct.pack("<II", 1, 20) + b"\0" * 8, "GLB header version"),
        ("a.glb", b"glTF" + struct.pack("<II", 2, 400) + b"\0" * 8, "GLB header length"),
        ("a.glb", b"{}", "GLB header"),
        ("a.gltf", b"{not json", "<json>"),
        ("a.gltf", b"[1, 2]", "<json>"),
        ("a.gltf", json.dumps({"asset": {"version": "1.0"}}).encode(), "asset.version"),
        (
            "a.gltf",
            json.dumps(
                {"asset": ASSET, "extensionsRequired": ["EXT_meshopt_compression"]}
            ).encode(),
            "extensionsRequired",
        ),
        (
            "a.gltf",
            json.dumps({"asset": ASSET, "buffers": [{"byteLength": 4}]}).encode(),
            "buffers[0].uri",
        ),
        (
            "a.gltf",
            json.dumps(
                {"asset": ASSET, "buffers": [{"uri": "gone.bin", "byteLength": 4}]}
            ).encode(),
            "buffers[0].uri",
        ),
        (
            "a.gltf",
            json.dumps(
                {"asset": ASSET, "buffers": [{"uri": "data:;base64,AAAA", "byteLength": 9}]}
            ).encode(),
            "buffers[0].byteLength",
        ),
    ],
)
def test_a_bad_file_is_refused_naming_its_field(tmp_path, name, content, field):
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(LoosefitInputError) as err:
        read_document(path)
    assert err.value.source == str(path) and err.value.field == field


def test_a_strided_view_of_interleaved_floats(tmp_path):
    # two VEC2 positions interleaved with a float each: stride 12 bytes
    data = np.array([1, 2, 9, 3, 4, 9], "<f4").tobytes()
    views = [{"buffer": 0, "byteLength": 24, "byteStride": 12}]
    acc = [{"bufferView": 0, "count": 2, "componentType": 5126, "type": "VEC2"}]
    got = read_accessor(_doc(acc, views, data, tmp_path), 0, "x")
    assert got.dtype == np.float64
    np.testing.assert_array_equal(got, [[1, 2], [3, 4]])


@pytest.mark.parametrize(
    ("ctype", "dtype", "values", "want"),
    [
        (5120, "<i1", [127, -127, -128, 0], [1.0, -1.0, -1.0, 0.0]),
        (5121, "<u1", [255, 0, 51, 102], [1.0, 0.0, 0.2, 0.4]),
        (5123, "<u2", [65535, 0, 13107, 0], [1.0, 0.0, 0.2, 0.0]),
    ],
)
def test_normalized_integers_are_scaled_to_unit_range(tmp_path, ctype, dtype, values, want):
    data = np.array(values, dtype).tobytes()
    views = [{"buffer": 0, "byteLength": len(data)}]
    acc = [{"bufferView": 0, "count": 1, "componentType": ctype, "type": "VEC4"}]
    acc[0]["normalized"] = True
    np.testing.assert_allclose(read_accessor(_doc(acc, views, data, tmp_path), 0, "x")[0], want)


def test_sparse_values_replace_a_few_of_the_zeros(tmp_path):
    data = np.array([2, 0], "<u2").tobytes() + np.array([7, 8, 9, 1, 2, 3], "<f4").tobytes()
    views = [{"buffer": 0, "byteLength": 4}, {"buffer": 0, "byteOffset": 4, "byteLength": 24}]
    sparse = {
        "count": 2,
        "indices": {"bufferView": 0, "componentType": 5123},
        "values": {"bufferView": 1},
    }
    acc = [{"count": 3, "componentType": 5126, "type": "VEC3", "sparse": sparse}]
    got = read_accessor(_doc(acc, views, data, tmp_path), 0, "x")
    np.testing.assert_array_equal(got, [[1, 2, 3], [0, 0, 0], [7, 8, 9]])
    sparse["indices"]["byteOffset"] = 0
    data_bad = np.array([5, 0], "<u2").tobytes() + data[4:]
    with pytest.raises(LoosefitInputError, match="accessors.0..sparse.indices"):
        read_accessor(_doc(acc, views, data_bad, tmp_path), 0, "x")


@pytest.mark.parametrize(
    ("accessor", "field"),
    [
        ({"count": 0, "componentType": 5126, "type": "VEC3"}, "accessors[0].count"),
        ({"count": 1, "componentType": 5130, "type": "VEC3"}, "accessors[0].componentType"),
        ({"count": 1, "componentType": 5126, "type": "VEC5"}, "accessors[0].type"),
        ({"count": 3, "componentType": 5126, "type": "VEC3"}, "accessors[0]"),  # 36 of 24 bytes
        ({"bufferView": 4, "count": 1}, "accessors[0].bufferView"),
        ({"count": 2, "componentType": 5126, "type": "VEC3"}, "accessors[0]"),  # a NaN in it
    ],
)
def test_a_bad_accessor_is_refused_naming_its_field(tmp_path, accessor, field):
    data = np.array([1.0, 2.0, 3.0, 4.0, np.nan, 6.0], "<f4").tobytes()
    accessor = {"bufferView": 0, "componentType": 5126, "type": "VEC3"} | accessor
    doc = _doc([accessor], [{"buffer": 0, "byteLength": 24}], data, tmp_path)
    with pytest.raises(LoosefitInputError) as err:
        read_accessor(doc, 0, "x")
    assert err.value.field == field
    with pytest.raises(LoosefitInputError, match=r"an index into 'accessors' \(0 to 0\)"):
        read_accessor(doc, 1, "x")


def test_the_first_element_before_a_nan_reads_and_a_viewless_accessor_is_zeros(tmp_path):
    data = np.array([1.0, 2.0, 3.0, 4.0, np.nan, 6.0], "<f4").tobytes()
    acc = [
        {"bufferView": 0, "count": 1, "componentType": 5126, "type": "VEC3"},
        {"bufferView": 0, "count": 2, "componentType": 5126, "type": "VEC3"},
        {"count": 2, "componentType": 5126, "type": "SCALAR"},
    ]
    doc = _doc(acc, [{"buffer": 0, "byteLength": 24}], data, tmp_path)
    np.testing.assert_array_equal(read_accessor(doc, 0, "x"), [[1, 2, 3]])
    with pytest.raises(LoosefitInputError, match="1 NaN or inf"):
        read_accessor(doc, 1, "x")
    np.testing.assert_array_equal(read_accessor(doc, 2, "x"), [[0], [0]])
