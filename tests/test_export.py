"""Exporters: USD written, read back and compared; bad input gives clear errors; the
``export`` command (PC2 + OBJ and OBJ sequences: tests/export/test_pointcache.py)."""

from __future__ import annotations

import os

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.export import AnimatedMesh, export_animation, read_pc2
from loosefit.export.meshes import in_up_axis
from tests.meshes import grid


def _meshes(T: int = 4) -> list[AnimatedMesh]:
    v, f = grid(4, -0.2, 0.2, 1.0)
    t = np.arange(T, dtype=np.float32)[:, None, None]
    garment = v[None] + t * np.float32([0.01, 0.0, -0.02])  # (T, 16, 3)
    uvs = (v[:, :2] + 0.2) / 0.4
    body_v, body_f = grid(3, -0.1, 0.1, 0.5)
    body = body_v[None] + t * np.float32([0.0, 0.03, 0.0])
    return [AnimatedMesh("garment", f, garment, uvs, f.copy()), AnimatedMesh("body", body_f, body)]


@pytest.mark.parametrize("suffix", [".usd", ".usda", ".usdc"])
def test_usd_holds_time_sampled_points_uvs_and_the_stage_units(tmp_path, suffix):
    from pxr import Usd, UsdGeom

    meshes = _meshes()
    path = tmp_path / f"anim{suffix}"
    assert export_animation(path, meshes, fps=30.0) == [path]
    assert not list(tmp_path.glob(".*partial*"))
    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert stage.GetTimeCodesPerSecond() == 30.0
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0, 3)
    for m in meshes:
        mesh = UsdGeom.Mesh(stage.GetPrimAtPath(f"/loosefit/{m.name}"))
        assert list(mesh.GetFaceVertexIndicesAttr().Get()) == m.faces.ravel().tolist()
        for t in range(m.num_frames):
            got = np.asarray(mesh.GetPointsAttr().Get(Usd.TimeCode(t)))
            np.testing.assert_array_equal(got, m.vertices[t])
    st = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/loosefit/garment")).GetPrimvar("st")
    np.testing.assert_allclose(
        np.asarray(st.ComputeFlattened()), meshes[0].uvs[meshes[0].face_uvs.ravel()]
    )


def test_bad_exports_are_clear_errors_and_leave_nothing(tmp_path):
    meshes = _meshes()
    with pytest.raises(LoosefitInputError, match="suffix"):
        export_animation(tmp_path / "anim.fbx", meshes, fps=30.0)
    with pytest.raises(LoosefitInputError, match="writable folder"):
        export_animation(tmp_path / "missing" / "anim.usd", meshes, fps=30.0)
    locked = tmp_path / "locked"
    locked.mkdir()
    os.chmod(locked, 0o500)
    try:
        if not os.access(locked, os.W_OK):  # (root writes anywhere)
            with pytest.raises(LoosefitInputError, match="not writable"):
                export_animation(locked / "anim.usdc", meshes, fps=30.0)
    finally:
        os.chmod(locked, 0o700)
    with pytest.raises(LoosefitInputError, match="frames each"):
        export_animation(
            tmp_path / "a.usd",
            [meshes[0], AnimatedMesh("body", meshes[1].faces, meshes[1].vertices[:2])],
            fps=30.0,
        )
    nan = meshes[0].vertices.copy()
    nan[2, 1, 0] = np.nan
    with pytest.raises(LoosefitInputError, match="frame 2"):
        AnimatedMesh("garment", meshes[0].faces, nan)
    with pytest.raises(LoosefitInputError, match="name"):
        AnimatedMesh("my garment", meshes[0].faces, meshes[0].vertices)
    # a failing writer leaves no file behind: the partial one is removed
    from loosefit.export import pointcache as ex

    def boom(*_a, **_k):
        raise RuntimeError("disk full")

    original = ex.PC2_HEADER
    try:
        ex.PC2_HEADER = type("H", (), {"pack": boom, "size": 32})()
        with pytest.raises(RuntimeError):
            export_animation(tmp_path / "x.pc2", meshes, fps=30.0)
    finally:
        ex.PC2_HEADER = original
    assert not list(tmp_path.glob("x*")) and not list(tmp_path.glob(".x*"))


def test_export_command_writes_a_dataset_sequence_with_the_posed_body(
    toy_dataset, avatar, tmp_path
):
    from loosefit.cli import main
    from loosefit.data.format import DatasetReader

    seq = DatasetReader(toy_dataset).read("c")
    assert main(["export", str(toy_dataset / "sequences" / "c.npz"), str(tmp_path / "c.pc2")]) == 0
    garment, _, _ = read_pc2(tmp_path / "c.pc2")  # Y up, as the OBJ beside it
    np.testing.assert_array_equal(garment, in_up_axis(seq.garment_vertices, "Y"))
    body, _, _ = read_pc2(tmp_path / "c_body.pc2")
    posed = avatar.pose_motion(seq.motion).vertices.numpy()
    np.testing.assert_allclose(body, in_up_axis(posed, "Y"), atol=1e-5)
    assert (
        main(
            [
                "export",
                str(toy_dataset / "sequences" / "c.npz"),
                str(tmp_path / "g.usda"),
                "--no-body",
            ]
        )
        == 0
    )
    assert "body" not in (tmp_path / "g.usda").read_text()
    assert main(["export", str(toy_dataset / "template.npz"), str(tmp_path / "t.usd")]) == 2
    assert main(["export", str(toy_dataset / "manifest.json"), str(tmp_path / "t.usd")]) == 2
    # an GarmentSequence's own file (what the API's save() and the demo write)
    from loosefit.sequence import GarmentSequence

    own = GarmentSequence(
        seq.motion,
        DatasetReader(toy_dataset).template,
        seq.garment_vertices,
        {"rig": "cmu_mb", "shape": {}},
    ).save(tmp_path / "own.npz")
    assert main(["export", str(own), str(tmp_path / "own.pc2"), "--no-body"]) == 0
    own_cache = read_pc2(tmp_path / "own.pc2")[0]
    np.testing.assert_array_equal(own_cache, in_up_axis(seq.garment_vertices, "Y"))
    assert main(["export", str(toy_dataset / "sequences" / "c.npz"), str(tmp_path / "c.fbx")]) == 2
    assert not list(tmp_path.glob("c.fbx*")) and not (tmp_path / "t.usd").exists()


def test_export_command_axes_and_body_as_points(toy_dataset, tmp_path):
    from pxr import Usd, UsdGeom

    from loosefit.cli import main
    from loosefit.data.format import DatasetReader

    seq = DatasetReader(toy_dataset).read("c")
    src = str(toy_dataset / "sequences" / "c.npz")
    for name, extra in (
        ("skin.usda", []),
        ("points.usda", ["--body-points"]),
        ("y.usda", ["--up-axis", "Y"]),
    ):
        assert main(["export", src, str(tmp_path / name), *extra]) == 0
    skin, points, y = (
        Usd.Stage.Open(str(tmp_path / n)) for n in ("skin.usda", "points.usda", "y.usda")
    )
    assert skin.GetPrimAtPath("/loosefit/body_rig").IsValid()
    assert not points.GetPrimAtPath("/loosefit/body_rig").IsValid()
    assert points.GetPrimAtPath("/loosefit/body").IsValid()
    assert UsdGeom.GetStageUpAxis(skin) == "Z" and UsdGeom.GetStageUpAxis(y) == "Y"
    g = UsdGeom.Mesh(y.GetPrimAtPath("/loosefit/garment")).GetPointsAttr().Get(Usd.TimeCode(1))
    v = seq.garment_vertices[1]  # Z up turned Y up: (x, y, z) -> (x, z, -y)
    np.testing.assert_allclose(np.asarray(g), np.stack([v[:, 0], v[:, 2], -v[:, 1]], 1), atol=1e-6)
    with pytest.raises(SystemExit):  # argparse names the choices
        main(["export", src, str(tmp_path / "bad.usda"), "--up-axis", "X"])
    assert not (tmp_path / "bad.usda").exists()
