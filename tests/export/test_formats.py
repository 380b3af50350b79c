"""USD with a skinned body, Alembic and glTF: written, read back by their own readers (or a
naive one written from the spec) and compared; the fallbacks and bad input."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.export import ExportConfig, export_animation
from tests.export.rigged import dressed

Y_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def test_usd_body_is_a_usdskel_rig_that_skins_to_the_body_and_passes_compliance(tmp_path):
    from pxr import Usd, UsdGeom, UsdSkel

    meshes = dressed(T=5)
    path = tmp_path / "rig.usdc"
    export_animation(path, meshes, fps=24.0)
    stage = Usd.Stage.Open(str(path))
    assert stage.GetTimeCodesPerSecond() == 24.0 and UsdGeom.GetStageMetersPerUnit(stage) == 1
    skel = UsdSkel.Skeleton(stage.GetPrimAtPath("/loosefit/body_rig/skeleton"))
    assert list(skel.GetJointsAttr().Get()) == ["Hips", "Hips/Spine", "Hips/Spine/Neck"]
    cache = UsdSkel.Cache()
    root = UsdSkel.Root(stage.GetPrimAtPath("/loosefit/body_rig"))
    cache.Populate(root, Usd.TraverseInstanceProxies())
    (binding,) = cache.ComputeSkelBindings(root, Usd.TraverseInstanceProxies())
    query = cache.GetSkelQuery(binding.GetSkeleton())
    skinning = binding.GetSkinningTargets()[0]
    for t in range(5):
        xf = query.ComputeSkinningTransforms(Usd.TimeCode(t))
        points = skinning.GetPrim().GetAttribute("points").Get()
        skinning.ComputeSkinnedPoints(xf, points, Usd.TimeCode(t))
        np.testing.assert_allclose(np.asarray(points), meshes[1].vertices[t], atol=1e-5)
    garment = UsdGeom.Mesh(stage.GetPrimAtPath("/loosefit/garment"))
    np.testing.assert_array_equal(np.asarray(garment.GetPointsAttr().Get(3)), meshes[0].vertices[3])
    assert _validation_errors(stage) == []
    bare = Usd.Stage.CreateInMemory()  # no default prim, up axis or units: the checks see it
    UsdGeom.Mesh.Define(bare, "/m")
    assert "MissingUpAxisMetadata" in _validation_errors(bare)


def _validation_errors(stage) -> list[str]:
    """usd-core's validators (UsdValidation, successor of UsdUtils.ComplianceChecker; the
    UsdSkel, UsdGeom and stage-metadata checks among them): the names of what failed."""
    from pxr import UsdValidation

    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    return [e.GetName() for e in UsdValidation.ValidationContext(validators).Validate(stage)]


def test_usd_body_as_points_on_request_and_when_it_has_no_rig_or_a_wrong_one(tmp_path):
    from pxr import Usd, UsdGeom

    meshes = dressed(T=3)
    export_animation(tmp_path / "a.usda", meshes, 30.0, ExportConfig(skinned_body=False))
    with pytest.warns(UserWarning, match="no rig"):
        export_animation(tmp_path / "b.usda", dressed(T=3, skinned=False), 30.0)
    off = dressed(T=3)
    off[1].vertices[2, 0, 0] += 0.001  # 1 mm the rig cannot make
    with pytest.warns(UserWarning, match="1.000 mm"):
        export_animation(tmp_path / "c.usda", off, 30.0)
    for name, m in (("a", meshes[1]), ("b", meshes[1]), ("c", off[1])):
        stage = Usd.Stage.Open(str(tmp_path / f"{name}.usda"))
        body = UsdGeom.Mesh(stage.GetPrimAtPath("/loosefit/body"))
        assert not stage.GetPrimAtPath("/loosefit/body_rig")
        np.testing.assert_array_equal(np.asarray(body.GetPointsAttr().Get(2)), m.vertices[2])


@pytest.mark.parametrize("suffix", [".usdc", ".usd", ".usda"])
def test_usd_saved_in_pieces_reads_back_every_frame(tmp_path, monkeypatch, suffix):
    """A binary layer is saved every SAVE_EVERY frames (so that a long sequence is not held
    whole in memory twice): every frame and the last extent read back as written."""
    from pxr import Usd, UsdGeom

    import loosefit.export.usd as usd

    monkeypatch.setattr(usd, "SAVE_EVERY", 4)
    meshes = dressed(T=11)
    meshes[0].vertices = (
        meshes[0].vertices + np.linspace(0, 0.1, 11, dtype=np.float32)[:, None, None]
    )  # every frame its own
    export_animation(tmp_path / f"a{suffix}", meshes, 30.0)
    stage = Usd.Stage.Open(str(tmp_path / f"a{suffix}"))
    garment = UsdGeom.Mesh(stage.GetPrimAtPath("/loosefit/garment"))
    assert garment.GetPointsAttr().GetTimeSamples() == list(range(11))
    for t in range(11):
        np.testing.assert_array_equal(
            np.asarray(garment.GetPointsAttr().Get(t)), meshes[0].vertices[t]
        )
    hi = np.asarray(garment.GetExtentAttr().Get(10))[1]
    np.testing.assert_allclose(hi, meshes[0].vertices[10].max(0), atol=1e-7)
    assert stage.GetEndTimeCode() == 10 and not list(tmp_path.glob(".*partial*"))


def test_usd_y_up_turns_points_and_rig(tmp_path):
    from pxr import Usd, UsdGeom

    export_animation(tmp_path / "y.usda", dressed(T=2), 30.0, ExportConfig(up_axis="Y"))
    stage = Usd.Stage.Open(str(tmp_path / "y.usda"))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    got = np.asarray(UsdGeom.Mesh(stage.GetPrimAtPath("/loosefit/garment")).GetPointsAttr().Get(1))
    np.testing.assert_allclose(got @ Y_TO_Z_UP.T, dressed(T=2)[0].vertices[1], atol=1e-6)


@pytest.mark.parametrize("up", ["Y", "Z"])
def test_alembic_point_caches_read_back_with_uvs_normals_and_the_frame_rate(tmp_path, up):
    pytest.importorskip("alembic3d", reason="the Alembic bindings: pip install 'loosefit[alembic]'")
    from alembic3d import Abc, AbcGeom

    meshes = dressed(T=4)
    path = tmp_path / "a.abc"
    assert export_animation(path, meshes, 25.0, ExportConfig(up_axis=up)) == [path]
    top = Abc.IArchive(str(path)).getTop()
    assert [c.getName() for c in top.children] == ["garment", "body"]
    to_z = Y_TO_Z_UP if up == "Y" else np.eye(3)
    for child, m in zip(top.children, meshes, strict=True):
        schema = AbcGeom.IPolyMesh(child, Abc.WrapExistingFlag.kWrapExisting).getSchema()
        assert schema.getNumSamples() == 4
        assert schema.getTimeSampling().getTimeSamplingType().getTimePerCycle() == 1 / 25
        for t in range(4):
            sample = schema.getValue(Abc.ISampleSelector(t / 25.0))
            got = np.asarray(memoryview(sample.getPositions())) @ to_z.T
            np.testing.assert_allclose(got, m.vertices[t], atol=1e-6)
        faces = np.asarray(memoryview(sample.getFaceIndices())).reshape(-1, 3)
        np.testing.assert_array_equal(faces[:, ::-1], m.faces)  # clockwise, as Alembic has it
    garment = AbcGeom.IPolyMesh(top.children[0], Abc.WrapExistingFlag.kWrapExisting).getSchema()
    uv = garment.getUVsParam().getIndexedValue(Abc.ISampleSelector(0.0))
    uvs = np.asarray(memoryview(uv.getVals()))[np.array(list(uv.getIndices()))].reshape(-1, 3, 2)
    np.testing.assert_allclose(uvs[:, ::-1], meshes[0].uvs[meshes[0].face_uvs])
    n = garment.getNormalsParam().getExpandedValue(Abc.ISampleSelector(0.0)).getVals()
    n = np.asarray(memoryview(n)) @ to_z.T
    a, b, c = meshes[0].vertices[0][meshes[0].faces[0]].astype(np.float64)
    face = np.cross(b - a, c - a)  # the flat grid's side its faces wind towards
    np.testing.assert_allclose(n, np.broadcast_to(face / np.linalg.norm(face), n.shape), atol=1e-5)


def _glb(path):
    """The JSON and the binary chunk of a .glb (the container, read from the spec)."""
    raw = path.read_bytes()
    magic, version, total = struct.unpack_from("<4sII", raw)
    assert (magic, version, total) == (b"glTF", 2, len(raw))
    n, kind = struct.unpack_from("<I4s", raw, 12)
    assert kind == b"JSON"
    doc = json.loads(raw[20 : 20 + n])
    m, kind = struct.unpack_from("<I4s", raw, 20 + n)
    assert kind == b"BIN\0" and m == doc["buffers"][0]["byteLength"]
    return doc, raw[28 + n : 28 + n + m]


def _accessor(doc, blob, i):
    a = doc["accessors"][i]
    width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}[a["type"]]
    dtype = {5126: "<f4", 5125: "<u4", 5123: "<u2"}[a["componentType"]]

    def view(v, count, w, dt):
        bv = doc["bufferViews"][v]
        return np.frombuffer(blob, dt, count * w, bv["byteOffset"]).reshape(count, w)

    out = (
        view(a["bufferView"], a["count"], width, dtype)
        if "bufferView" in a
        else np.zeros((a["count"], width), dtype)
    )
    if "sparse" in a:
        s, out = a["sparse"], out.copy()
        idx = view(s["indices"]["bufferView"], s["count"], 1, "<u4")[:, 0]
        out[idx] = view(s["values"]["bufferView"], s["count"], width, dtype)
    return out


def _quat_matrix(x, y, z, w):
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def test_gltf_skinned_body_and_morph_target_garment_evaluate_to_the_meshes(tmp_path):
    """A naive glTF player: node TRS from the animation, skinning by the spec, morph
    targets weighted; every frame matches, in metres, after glTF's Y up."""
    meshes = dressed(T=4)
    path = tmp_path / "a.glb"
    export_animation(path, meshes, 30.0)
    doc, blob = _glb(path)
    (anim,) = doc["animations"]
    times = _accessor(doc, blob, anim["samplers"][0]["input"])[:, 0]
    np.testing.assert_allclose(times, np.arange(4) / 30.0)
    nodes = {n["name"]: i for i, n in enumerate(doc["nodes"])}
    parent = {c: i for i, n in enumerate(doc["nodes"]) for c in n.get("children", [])}
    for t in range(4):
        local = {i: np.eye(4) for i in range(len(doc["nodes"]))}
        weights = {}
        for ch in anim["channels"]:
            out = _accessor(doc, blob, anim["samplers"][ch["sampler"]]["output"])
            node, kind = ch["target"]["node"], ch["target"]["path"]
            if kind == "translation":
                local[node][:3, 3] = out[t]
            elif kind == "rotation":
                local[node][:3, :3] = _quat_matrix(*out[t])
            else:
                weights[node] = out[:, 0].reshape(4, -1)[t]

        def world(i, local=local):
            return local[i] if i not in parent else world(parent[i], local) @ local[i]

        garment = doc["meshes"][doc["nodes"][nodes["garment"]]["mesh"]]["primitives"][0]
        pos = _accessor(doc, blob, garment["attributes"]["POSITION"]).astype(np.float64)
        for k, target in enumerate(garment["targets"]):
            pos = pos + weights[nodes["garment"]][k] * _accessor(doc, blob, target["POSITION"])
        source = doc["meshes"][0]["extras"]["loosefit_vertex"]
        np.testing.assert_allclose(pos @ Y_TO_Z_UP.T, meshes[0].vertices[t][source], atol=1e-6)

        body = doc["nodes"][nodes["body"]]
        prim = doc["meshes"][body["mesh"]]["primitives"][0]
        skin = doc["skins"][body["skin"]]
        ibm = _accessor(doc, blob, skin["inverseBindMatrices"]).reshape(-1, 4, 4).transpose(0, 2, 1)
        joint = np.stack([world(j) @ ibm[k] for k, j in enumerate(skin["joints"])])
        rest = _accessor(doc, blob, prim["attributes"]["POSITION"]).astype(np.float64)
        posed = np.zeros_like(rest)
        for s in range(2):
            J = _accessor(doc, blob, prim["attributes"][f"JOINTS_{s}"]).astype(int)
            W = _accessor(doc, blob, prim["attributes"][f"WEIGHTS_{s}"])
            for c in range(4):
                M = joint[J[:, c]]
                posed += W[:, c, None] * ((M[:, :3, :3] @ rest[:, :, None])[..., 0] + M[:, :3, 3])
        np.testing.assert_allclose(posed @ Y_TO_Z_UP.T, meshes[1].vertices[t], atol=1e-5)
    assert [doc["nodes"][j]["name"] for j in skin["joints"]] == ["Hips", "Spine", "Neck"]


def test_unknown_suffix_names_the_formats_and_a_failed_write_leaves_nothing(tmp_path, monkeypatch):
    with pytest.raises(LoosefitInputError, match=r"\.abc.*\.glb.*got|\.abc, \.glb"):
        export_animation(tmp_path / "a.fbx", dressed(T=2), 30.0)
    from loosefit.export import gltf

    def broken(*_a, **_k):
        raise RuntimeError("disk full")

    monkeypatch.setattr(gltf, "continuous_quaternions", broken)
    with pytest.raises(RuntimeError):
        export_animation(tmp_path / "a.glb", dressed(T=2), 30.0)
    assert list(tmp_path.iterdir()) == []
