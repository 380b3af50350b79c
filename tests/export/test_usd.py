"""USD: quaternions that take the short way, UsdSkel's joint paths, and a stage whose points,
topology, UVs, axes and timing read back as written."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.export.meshes import AnimatedMesh, ExportConfig, Skin
from loosefit.export.usd import continuous_quaternions, export_usd, joint_paths
from tests.meshes import grid


def _rz(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def test_quaternions_follow_their_previous_frame_s_sign():
    angles = np.linspace(0, 3 * np.pi, 13)  # past a full turn: a quaternion's sign would flip
    q = continuous_quaternions(np.stack([_rz(a) for a in angles])[:, None])
    assert q.shape == (13, 1, 4) and q.dtype == np.float32
    assert ((q[1:, 0] * q[:-1, 0]).sum(-1) > 0).all()  # each next to the one before
    # each still the rotation: (cos a/2, 0, 0, sin a/2) up to the one sign the path picked
    want = np.stack([np.cos(angles / 2), 0 * angles, 0 * angles, np.sin(angles / 2)], 1)
    sign = np.sign((q[:, 0] * want).sum(-1))
    np.testing.assert_allclose(q[:, 0], sign[:, None] * want, atol=1e-6)
    # the path is (cos a/2, 0, 0, sin a/2) itself: past half a turn w < 0, not flipped back
    assert (sign == 1).all() and (
        q[(angles > 1.1 * np.pi) & (angles < 2.9 * np.pi), 0, 0] < -0.1
    ).all()


def test_joint_paths_run_from_the_root():
    skin = Skin(
        ("Hips", "LowerBack", "Spine", "LeftUpLeg"),
        [-1, 0, 1, 0],
        np.zeros((1, 3)),
        np.tile(np.eye(4), (4, 1, 1)),
        np.ones((1, 1)),
        np.zeros((1, 1), int),
        np.tile(np.eye(4), (1, 4, 1, 1)),
    )
    assert joint_paths(skin) == ["Hips", "Hips/LowerBack", "Hips/LowerBack/Spine", "Hips/LeftUpLeg"]


def _garment(T: int = 3) -> AnimatedMesh:
    v, f = grid(3, -0.2, 0.2, 1.0)
    moves = v[None] + np.arange(T, dtype=np.float32)[:, None, None] * np.float32(
        [0.01, 0.02, -0.03]
    )
    uvs = (v[:, :2] + 0.2) / 0.4
    return AnimatedMesh("garment", f, moves, uvs, f.copy())


@pytest.mark.parametrize("up", ["Z", "Y"])
def test_a_stage_reads_back_as_written(tmp_path, up):
    from pxr import Usd, UsdGeom

    m = _garment()
    path = tmp_path / "g.usda"
    assert export_usd(path, [m], 24.0, ExportConfig(up_axis=up)) == [path]
    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageUpAxis(stage) == up and UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert stage.GetTimeCodesPerSecond() == 24.0 and stage.GetFramesPerSecond() == 24.0
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0, 2)
    assert stage.GetDefaultPrim().GetPath() == "/loosefit"
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/loosefit/garment"))
    np.testing.assert_array_equal(
        np.asarray(mesh.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3), m.faces
    )
    to_z = np.eye(3) if up == "Z" else np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])
    for t in range(3):
        points = np.asarray(mesh.GetPointsAttr().Get(t), np.float64) @ to_z.T
        np.testing.assert_allclose(points, m.vertices[t], atol=1e-6)
    st = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
    assert st.GetInterpolation() == "faceVarying"
    np.testing.assert_allclose(
        np.asarray(st.ComputeFlattened()), m.uvs[m.face_uvs.ravel()], atol=1e-7
    )


def test_without_usd_core_the_error_says_how_to_install_it(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pxr", None)  # import pxr fails
    with pytest.raises(
        LoosefitInputError, match=r"g\.usd: field '<format>': expected usd-core installed"
    ):
        export_usd(tmp_path / "g.usd", [_garment()], 24.0)
    assert not (tmp_path / "g.usd").exists()
