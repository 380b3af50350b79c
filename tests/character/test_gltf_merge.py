import json
import struct

import numpy as np
import pytest

from loosefit.character import read_character
from loosefit.character.gltf_merge import add_animated_mesh, write_glb
from loosefit.export.meshes import Z_TO_Y_UP, AnimatedMesh
from loosefit.motion.gltf_file import read_accessor, read_document

FRAMES = 6


def test_a_glb_is_its_header_a_json_chunk_and_a_binary_chunk(tmp_path):
    doc = {"asset": {"version": "2.0"}, "buffers": [{"byteLength": 8}], "nodes": [{"name": "é"}]}
    data = np.arange(2, dtype="<f4").tobytes()
    path = write_glb(tmp_path / "a.glb", doc, data)
    raw = path.read_bytes()
    magic, version, total = struct.unpack_from("<4sII", raw)
    assert (magic, version, total) == (b"glTF", 2, len(raw))
    size, kind = struct.unpack_from("<I4s", raw, 12)
    assert kind == b"JSON" and size % 4 == 0
    assert json.loads(raw[20 : 20 + size]) == doc
    assert struct.unpack_from("<I4s", raw, 20 + size) == (8, b"BIN\0")
    back = read_document(path)
    assert back.gltf == doc and back.buffers == [data]


@pytest.fixture(scope="module")
def merged(character, tmp_path_factory):
    """The character's file with a triangle added, rising 1 cm a frame, and the mesh."""
    base = read_character(character[0], 20.0)  # sampled at 20 fps: times k / 20
    v = np.array([[0.0, 0.0, 1.0], [0.1, 0.0, 1.0], [0.0, 0.1, 1.0]], np.float32)
    frames = v[None] + np.float32([0.0, 0.0, 0.01]) * np.arange(FRAMES)[:, None, None]
    mesh = AnimatedMesh("garment", np.array([[0, 1, 2]]), frames)
    out = add_animated_mesh(base, mesh, tmp_path_factory.mktemp("merge") / "dressed.glb")
    return base, mesh, out


def test_everything_of_theirs_is_kept(merged):
    base, _, out = merged
    theirs, ours = read_document(base.path), read_document(out)
    for key in ("nodes", "meshes", "skins"):
        n = len(theirs.gltf.get(key, []))
        assert ours.gltf[key][:n] == theirs.gltf[key], key
    for i in range(len(theirs.gltf["accessors"])):  # their data, moved but unchanged
        np.testing.assert_array_equal(read_accessor(ours, i, "a"), read_accessor(theirs, i, "a"))
    assert len(ours.buffers) == 1
    again = read_character(out, 20.0)
    np.testing.assert_array_equal(again.posed(0, FRAMES), base.posed(0, FRAMES))


def test_the_mesh_moves_on_their_timeline_one_morph_target_a_frame(merged):
    base, mesh, out = merged
    theirs, ours = read_document(base.path), read_document(out)
    node = len(theirs.gltf["nodes"])
    assert node in ours.gltf["scenes"][ours.gltf.get("scene", 0)]["nodes"]
    prim = ours.gltf["meshes"][ours.gltf["nodes"][node]["mesh"]]["primitives"][0]
    anim = ours.gltf["animations"][base.animation]
    channel = next(c for c in anim["channels"] if c["target"]["node"] == node)
    assert channel["target"]["path"] == "weights"
    sampler = anim["samplers"][channel["sampler"]]
    times = read_accessor(ours, sampler["input"], "t")[:, 0]
    np.testing.assert_allclose(times, base.times[:FRAMES])
    np.testing.assert_allclose(times - times[0], np.arange(FRAMES) / 20, atol=1e-6)
    weights = read_accessor(ours, sampler["output"], "w").reshape(FRAMES, -1)
    position = read_accessor(ours, prim["attributes"]["POSITION"], "p")
    for k in range(FRAMES):  # the frame's weights blend the targets into its vertices, Y up
        shape = position + sum(
            w * read_accessor(ours, target["POSITION"], "d")
            for w, target in zip(weights[k], prim["targets"], strict=True)
        )
        np.testing.assert_allclose(shape, mesh.vertices[k] @ Z_TO_Y_UP.T, atol=1e-6)
