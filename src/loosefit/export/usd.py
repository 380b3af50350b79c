"""USD (``.usd``, ``.usdc``, ``.usda``) through Pixar's ``usd-core``.

The stage (default prim ``/loosefit``) declares its up axis (Z unless asked for Y), metres
(``metersPerUnit = 1``), the frame rate (``timeCodesPerSecond``) and the frames (time codes
0 to T - 1). Each mesh without a rig is a ``UsdGeom.Mesh`` at ``/loosefit/NAME`` whose
points are time-sampled on every frame, UVs as the face-varying ``st`` primvar. A mesh with
a rig (the body) is written with ``UsdSkel``: a ``SkelRoot`` at ``/loosefit/NAME_rig``
holding the ``Skeleton`` (the capture's joints, in its order and by its names, with their
bind and rest transforms), a ``SkelAnimation`` (a translation, rotation and scale per
joint and frame) and the mesh at its bind pose with its joint indices and weights: a
few MB where the same body as points is about 160 KB a frame.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from loosefit.atomic import atomic_path
from loosefit.errors import LoosefitInputError
from loosefit.export.meshes import (
    Z_TO_Y_UP,
    AnimatedMesh,
    ExportConfig,
    Skin,
    check_meshes,
    skin_to_write,
)
from loosefit.geometry.rotations import matrix_to_quat


def continuous_quaternions(rotations: np.ndarray) -> np.ndarray:
    """(T, J, 4) ``(w, x, y, z)`` quaternions of (T, J, 3, 3) rotations, each joint's sign
    chosen to follow its previous frame's (so interpolation takes the short way)."""
    q = matrix_to_quat(rotations).astype(np.float64)  # (T, J, 4)
    for t in range(1, len(q)):
        flip = (q[t] * q[t - 1]).sum(-1) < 0
        q[t, flip] *= -1
    return q.astype(np.float32)


def joint_paths(skin: Skin) -> list[str]:
    """UsdSkel's joint tokens: each joint's path from the root, ``Hips/LowerBack/...``."""
    paths: list[str] = []
    for name, p in zip(skin.joint_names, skin.parents, strict=True):
        paths.append(name if p < 0 else f"{paths[p]}/{name}")
    return paths


def _pxr(path: Path):
    try:
        from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt
    except ImportError as exc:  # a dependency of loosefit; a clear message if it is missing
        raise LoosefitInputError(
            path, "<format>", "usd-core installed (pip install usd-core)", str(exc)
        ) from exc
    return Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt


def _matrices(Gf, Vt, m: np.ndarray):
    """(N, 4, 4) column-vector matrices as USD's row-vector ``Matrix4dArray``."""
    return Vt.Matrix4dArray([Gf.Matrix4d(*np.asarray(a).T.ravel().tolist()) for a in m])


def _define_mesh(stage, path: str, m: AnimatedMesh, Sdf, UsdGeom, Vt):
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(m.faces)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(m.faces.astype(np.int32).ravel()))
    if m.uvs is not None:
        st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(
            "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying
        )
        st.Set(Vt.Vec2fArray.FromNumpy(m.uvs))
        st.SetIndices(Vt.IntArray.FromNumpy(m.face_uvs.astype(np.int32).ravel()))
    return mesh


# A binary (crate) layer saved every this many frames: crate appends the new samples to the
# file and lets go of them, so a long sequence is never held whole a second time in memory
# (10,000 frames of a 2,401-vertex garment: 19 MiB at the peak instead of 280).
SAVE_EVERY = 256


def _saver(stage):
    """A function of the frame just written that saves a crate layer every
    :data:`SAVE_EVERY` frames (a text layer is written once, at the end)."""
    layer = stage.GetRootLayer()
    kind = layer.GetFileFormat().formatId  # .usd is crate unless USD is told otherwise
    crate = kind == "usdc" or (
        kind == "usd" and os.environ.get("USD_DEFAULT_FILE_FORMAT") != "usda"
    )

    def after(t: int) -> None:
        if crate and (t + 1) % SAVE_EVERY == 0:
            layer.Save()

    return after


def _write_points(mesh, vertices: np.ndarray, rotation, Gf, Usd, Vt, *, after=None) -> None:
    points, extent = mesh.CreatePointsAttr(), mesh.CreateExtentAttr()
    for t in range(len(vertices)):
        v = vertices[t] if rotation is None else (vertices[t] @ rotation.T).astype(np.float32)
        points.Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(v)), Usd.TimeCode(t))
        lo, hi = v.min(0).tolist(), v.max(0).tolist()
        extent.Set(Vt.Vec3fArray([Gf.Vec3f(*lo), Gf.Vec3f(*hi)]), Usd.TimeCode(t))
        if after is not None:
            after(t)


def _write_skinned(stage, root: str, m: AnimatedMesh, skin: Skin, rotation, mods) -> None:
    Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt = mods
    UsdSkel.Root.Define(stage, root)
    skeleton = UsdSkel.Skeleton.Define(stage, f"{root}/skeleton")
    joints = Vt.TokenArray(joint_paths(skin))
    skeleton.CreateJointsAttr(joints)
    skeleton.CreateJointNamesAttr(Vt.TokenArray(list(skin.joint_names)))
    skeleton.CreateBindTransformsAttr(_matrices(Gf, Vt, skin.bind_poses))
    skeleton.CreateRestTransformsAttr(_matrices(Gf, Vt, skin.local_bind_poses()))

    anim = UsdSkel.Animation.Define(stage, f"{root}/animation")
    anim.CreateJointsAttr(joints)
    local = skin.local_poses()  # (T, J, 4, 4)
    quats = continuous_quaternions(local[..., :3, :3])  # (T, J, 4) w, x, y, z
    scales = Vt.Vec3hArray.FromNumpy(np.ones((len(skin.joint_names), 3), np.float16))
    anim.CreateScalesAttr().Set(scales)
    translations, rotations = anim.CreateTranslationsAttr(), anim.CreateRotationsAttr()
    for t in range(len(local)):
        code = Usd.TimeCode(t)
        translations.Set(Vt.Vec3fArray.FromNumpy(local[t, :, :3, 3].astype(np.float32)), code)
        q = quats[t]
        rotations.Set(
            Vt.QuatfArray([Gf.Quatf(float(a), float(b), float(c), float(d)) for a, b, c, d in q]),
            code,
        )
    UsdSkel.BindingAPI.Apply(skeleton.GetPrim()).CreateAnimationSourceRel().SetTargets(
        [anim.GetPath()]
    )

    mesh = _define_mesh(stage, f"{root}/{m.name}", m, Sdf, UsdGeom, Vt)
    rest = skin.rest_vertices.astype(np.float32)
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(rest))
    # the extent over the whole animation (the mesh's own points are at rest)
    corners = np.stack([m.vertices.min((0, 1)), m.vertices.max((0, 1))])  # (2, 3), Z up
    if rotation is not None:  # an axis permutation with signs: the box's corners turn
        corners = corners @ rotation.T
    lo = np.minimum(corners.min(0), rest.min(0))
    hi = np.maximum(corners.max(0), rest.max(0))
    mesh.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*lo.tolist()), Gf.Vec3f(*hi.tolist())]))
    binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
    binding.CreateSkeletonRel().SetTargets([skeleton.GetPath()])
    K = skin.weights.shape[1]
    binding.CreateJointIndicesPrimvar(False, K).Set(
        Vt.IntArray.FromNumpy(skin.indices.astype(np.int32).ravel())
    )
    binding.CreateJointWeightsPrimvar(False, K).Set(
        Vt.FloatArray.FromNumpy(skin.weights.astype(np.float32).ravel())
    )
    binding.CreateGeomBindTransformAttr(Gf.Matrix4d(1.0))


def export_usd(
    path: Path, meshes: list[AnimatedMesh], fps: float, config: ExportConfig | None = None
) -> list[Path]:
    """A USD stage (format by suffix): points time-sampled, a rigged body skinned."""
    config = config or ExportConfig()
    mods = _pxr(path)
    Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt = mods
    T = check_meshes(meshes, fps, path)
    y_up = config.up_axis == "Y"
    rotation = Z_TO_Y_UP if y_up else None
    with atomic_path(path) as tmp:
        stage = Usd.Stage.CreateNew(str(tmp))
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y if y_up else UsdGeom.Tokens.z)
        UsdGeom.SetStageMetersPerUnit(stage, 1.0)
        stage.SetTimeCodesPerSecond(float(fps))
        stage.SetFramesPerSecond(float(fps))
        stage.SetStartTimeCode(0)
        stage.SetEndTimeCode(T - 1)
        root = UsdGeom.Xform.Define(stage, "/loosefit")
        stage.SetDefaultPrim(root.GetPrim())
        for m in meshes:
            skin = skin_to_write(m, config, path)
            if skin is not None:
                skin = skin if rotation is None else skin.transformed(rotation)
                _write_skinned(stage, f"/loosefit/{m.name}_rig", m, skin, rotation, mods)
            else:
                mesh = _define_mesh(stage, f"/loosefit/{m.name}", m, Sdf, UsdGeom, Vt)
                _write_points(mesh, m.vertices, rotation, Gf, Usd, Vt, after=_saver(stage))
        stage.GetRootLayer().Save()
        del stage
    return [path]
