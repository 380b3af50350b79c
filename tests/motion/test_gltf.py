"""glTF/GLB skins and animations as motions."""

import dataclasses
import json
import time

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.motion.bvh import read_bvh
from loosefit.motion.gltf import read_gltf
from loosefit.motion.gltf_animation import DEFAULT_FPS
from loosefit.motion.retarget import RetargetConfig, resolve_joint_map
from loosefit.types import Motion
from tests.motion.bvh_conventions import ALL_CONVENTIONS, motion_error, write_convention_bvh
from tests.motion.gltf_writer import write_document, write_gltf

CM = 0.01


@pytest.fixture(scope="module")
def dance(avatar):
    from loosefit.motion.motions import load_motion

    return load_motion("dance:3", avatar, seed=1)  # 90 frames at 30 fps


def _clip(tmp_path, avatar, dance, conv="mixamo"):
    """The dance written as a BVH in a convention, read back: the clip a glTF carries."""
    path = tmp_path / f"{conv}.bvh"
    write_convention_bvh(path, ALL_CONVENTIONS[conv], avatar.skeleton, dance, avatar.floor_height)
    return read_bvh(path)


@pytest.mark.parametrize(
    "conv, file, options",
    [
        ("mixamo", "mixamo.glb", {}),  # bone frames, an Armature turned and scaled 0.01
        ("mixamo", "frame0.glb", {"node_rest": "frame0"}),  # the rest from the bind matrices
        ("unreal", "unreal.gltf", {"quantize": True}),  # embedded buffer, int16 rotations
        ("smpl", "nobind.glb", {"inverse_bind": False}),  # the rest from the nodes
        ("daz", "plain.gltf", {"bone_frames": False, "armature_scale": 1.0}),
        ("studio-far", "far.glb", {}),  # hips metres from a still root joint, bones along X
    ],
)
def test_a_gltf_animation_round_trips_to_the_same_motion(
    avatar, dance, tmp_path, conv, file, options
):
    from loosefit.motion.motions import load_motion

    path = write_gltf(tmp_path / file, _clip(tmp_path, avatar, dance, conv), **options)
    t = time.perf_counter()
    back = load_motion(str(path), avatar)
    seconds = time.perf_counter() - t
    assert back.num_frames == dance.num_frames and back.fps == 30
    joints = ALL_CONVENTIONS[conv].joints
    assert resolve_joint_map(read_gltf(path)).joint_map.joints == joints
    mean, worst = motion_error(avatar, dance, back, joints)
    print(
        f"{file}: mean joint error {mean / CM:.2g} cm, max {worst / CM:.2g} cm, "
        f"{path.stat().st_size / 1e3:.0f} kB read and retargeted in {seconds:.2f} s"
    )
    assert mean < 1 * CM and worst < 2 * CM


def test_animation_and_skin_picked_by_name_or_index(avatar, dance, tmp_path):
    from loosefit.motion.motions import load_motion

    clip = _clip(tmp_path, avatar, dance)
    path = write_gltf(tmp_path / "two.glb", clip, idle_first=True, prop_skin=True)
    idle = read_gltf(path)  # the first animation: one second standing still
    assert idle.num_frames == 31 and "'idle' (1 of 2" in idle.meta["report"]["animation"]
    assert "'body' (2 of 2)" in idle.meta["report"]["skin"]  # the skin it animates
    for pick in ("dance", "1", 1):
        assert read_gltf(path, animation=pick).num_frames == dance.num_frames
    joints = ALL_CONVENTIONS["mixamo"].joints
    for spec, cfg in (
        (f"animation:dance:{path}", None),
        (str(path), RetargetConfig(animation="dance")),
    ):
        back = load_motion(spec, avatar, retarget=cfg)
        assert motion_error(avatar, dance, back, joints)[0] < 1 * CM
    with pytest.raises(LoosefitInputError, match=r"two\.glb.*'animations'.*'walk'.*idle"):
        read_gltf(path, animation="walk")
    with pytest.raises(LoosefitInputError, match=r"two\.glb.*'skins'.*'hat'"):
        read_gltf(path, skin="hat")
    with pytest.raises(LoosefitInputError, match=r"two\.glb.*channels.*drives none of its 1"):
        read_gltf(path, skin="prop")


def test_keyframes_set_the_rate_and_are_resampled(avatar, dance, tmp_path):
    from loosefit.motion.motions import load_motion

    clip = _clip(tmp_path, avatar, dance)
    fast = dataclasses.replace(clip, frame_time=1 / 60)  # the same keys, twice as fast
    path = write_gltf(tmp_path / "60.glb", fast)
    assert read_gltf(path).fps == 60 and read_gltf(path).num_frames == dance.num_frames
    assert read_gltf(path, fps=30).num_frames == (dance.num_frames + 1) // 2
    back = load_motion(str(path), avatar, fps=30)  # resampled by the retargeting
    assert back.fps == 30 and back.num_frames == (dance.num_frames + 1) // 2
    every_other = Motion(dance.joint_names, dance.rotations[::2], dance.root_translation[::2], 30)
    assert motion_error(avatar, every_other, back, ALL_CONVENTIONS["mixamo"].joints)[0] < 1 * CM
    slow = dataclasses.replace(clip, frame_time=0.5)  # sparse keys: sampled at 30 fps
    got = read_gltf(write_gltf(tmp_path / "slow.glb", slow))
    assert got.fps == DEFAULT_FPS and got.num_frames == int((dance.num_frames - 1) * 0.5 * 30) + 1


def _document(path):
    """A small valid GLB's JSON and buffer to break."""
    raw = path.read_bytes()
    n = int.from_bytes(raw[12:16], "little")
    doc = json.loads(raw[20 : 20 + n])
    data = raw[20 + n + 8 :]
    return doc, data


def test_bad_gltf_files_name_the_file_and_the_field(avatar, dance, tmp_path):
    clip = _clip(tmp_path, avatar, dance)
    good = write_gltf(tmp_path / "good.glb", clip)
    doc, data = _document(good)

    def broken(name: str, change) -> str:
        d = json.loads(json.dumps(doc))
        change(d)
        return str(write_document(tmp_path / name, d, data))

    cases = {
        broken("noskin.glb", lambda d: d.pop("skins")): r"noskin\.glb.*'skins'.*a skin.*none",
        broken("noanim.glb", lambda d: d.pop("animations")): r"noanim\.glb.*'animations'.*none",
        broken(
            "elsewhere.glb",
            lambda d: [
                c["target"].update(node=len(d["nodes"]) - 1) for c in d["animations"][0]["channels"]
            ],
        ): r"elsewhere\.glb.*'animations\[0\]\.channels'.*drives none of its",
        broken("v1.glb", lambda d: d["asset"].update(version="1.0")): r"v1\.glb.*asset\.version",
        broken(
            "acc.glb", lambda d: d["accessors"][1].update(count=10**6)
        ): r"acc\.glb.*'accessors\[1\]'.*inside bufferViews",
        broken(
            "interp.glb", lambda d: d["animations"][0]["samplers"][0].update(interpolation="SMOOTH")
        ): r"interp\.glb.*samplers\[0\]\.interpolation",
        broken(
            "node.glb", lambda d: d["animations"][0]["channels"][0]["target"].update(node=999)
        ): r"node\.glb.*channels\[0\]\.target\.node",
        broken("cycle.glb", lambda d: d["nodes"][1].update(children=[0])): r"cycle\.glb.*nodes",
        broken(
            "ibm.glb", lambda d: d["skins"][0]["joints"].pop()
        ): r"ibm\.glb.*inverseBindMatrices.*one per joint",
        broken(
            "type.glb", lambda d: d["nodes"][0].update(rotation="up")
        ): r"type\.glb.*'nodes\[0\]\.rotation'",
    }
    raw = good.read_bytes()
    (tmp_path / "magic.glb").write_bytes(b"GLTF" + raw[4:])
    cases[str(tmp_path / "magic.glb")] = r"magic\.glb.*GLB header.*'glTF'"
    (tmp_path / "cut.glb").write_bytes(raw[: len(raw) // 2])
    cases[str(tmp_path / "cut.glb")] = r"cut\.glb.*GLB header length.*truncated"
    (tmp_path / "text.gltf").write_text('{"asset": {"version": "2.0"}, "nodes": [')
    cases[str(tmp_path / "text.gltf")] = r"text\.gltf.*'<json>'.*valid JSON"
    (tmp_path / "far.gltf").write_text(
        json.dumps({**doc, "buffers": [{"byteLength": len(data), "uri": "far.bin"}]})
    )
    cases[str(tmp_path / "far.gltf")] = r"far\.gltf.*'buffers\[0\]\.uri'.*far\.bin"
    for file, pattern in cases.items():
        with pytest.raises(LoosefitInputError, match=pattern):
            read_gltf(file)
    from loosefit.motion.motions import load_motion

    with pytest.raises(LoosefitInputError, match=r"missing\.glb.*an existing GLB file"):
        load_motion(str(tmp_path / "missing.glb"), avatar)


def test_inspect_motion_reads_gltf(avatar, dance, tmp_path):
    from loosefit.motion.inspect import inspect_motion

    path = write_gltf(tmp_path / "m.glb", _clip(tmp_path, avatar, dance), idle_first=True)
    text = inspect_motion(path, RetargetConfig(animation="dance")).format()
    for part in (
        "m.glb",
        "frames: 90 at 30 fps",
        "units: m (glTF",
        "animation: 'dance' (2 of 2",
        "skin: 'body'",
        "rest pose: the skin's bind pose",
        "mixamorig:LeftUpLeg",
        "joint map: auto-matched",
    ):
        assert part in text, (part, text)


def test_accessors_read_strides_normalized_integers_and_sparse_values(tmp_path):
    from loosefit.motion.gltf_file import GltfDocument, read_accessor

    floats = np.arange(12, dtype=np.float32).reshape(4, 3)
    strided = np.zeros((4, 5), np.float32)  # 3 floats and 8 bytes of padding per element
    strided[:, :3] = floats
    shorts = np.array([[32767, -32767, 0, -32768]], np.int16)
    indices = np.array([1, 3], np.uint16)
    values = np.array([[-1, -1, -1], [-2, -2, -2]], np.float32)
    data = strided.tobytes() + shorts.tobytes() + indices.tobytes() + values.tobytes()
    o = [0, 80, 88, 92]
    gltf = {
        "bufferViews": [
            {"buffer": 0, "byteOffset": o[0], "byteLength": 80, "byteStride": 20},
            {"buffer": 0, "byteOffset": o[1], "byteLength": 8},
            {"buffer": 0, "byteOffset": o[2], "byteLength": 4},
            {"buffer": 0, "byteOffset": o[3], "byteLength": 24},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"},
            {
                "bufferView": 1,
                "componentType": 5122,
                "count": 1,
                "type": "VEC4",
                "normalized": True,
            },
            {
                "bufferView": 0,
                "componentType": 5126,
                "count": 4,
                "type": "VEC3",
                "sparse": {
                    "count": 2,
                    "indices": {"bufferView": 2, "componentType": 5123},
                    "values": {"bufferView": 3},
                },
            },
            {"componentType": 5126, "count": 2, "type": "SCALAR"},
        ],
    }
    doc = GltfDocument(tmp_path / "a.gltf", gltf, [data])
    assert np.array_equal(read_accessor(doc, 0, "x"), floats)
    assert np.allclose(read_accessor(doc, 1, "x"), [[1, -1, 0, -1]])
    want = floats.copy()
    want[[1, 3]] = values
    assert np.array_equal(read_accessor(doc, 2, "x"), want)
    assert np.array_equal(read_accessor(doc, 3, "x"), [[0], [0]])  # no bufferView: zeros
    with pytest.raises(LoosefitInputError, match=r"a\.gltf.*'where'.*an index into 'accessors'"):
        read_accessor(doc, 7, "where")
