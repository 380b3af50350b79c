"""Alembic (``.abc``, Ogawa) through the PyAlembic bindings (``pip install alembic3d``).

One ``PolyMesh`` per mesh under the archive's top, its positions sampled on every frame
with a uniform time sampling of ``1 / fps`` seconds from 0 (the frame rate travels with
the file), UVs as the face-varying ``uv`` parameter, the garment's vertex normals as ``N``
on every frame, metres. Alembic's faces wind clockwise (Maya's and Houdini's readers and
Blender's reverse them), so each triangle is written reversed. The axes are Y up (the
convention of Alembic and of the tools that read it; Blender's importer turns them to Z)
unless ``ExportConfig.up_axis`` says Z. Every mesh is a point cache: Alembic has no
skinning. Frames are written one at a time, so a long sequence is never copied whole.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from loosefit.atomic import atomic_path
from loosefit.errors import LoosefitInputError
from loosefit.export.meshes import (
    Z_TO_Y_UP,
    AnimatedMesh,
    ExportConfig,
    check_meshes,
    vertex_normals_np,
)


def _alembic(path: Path):
    try:
        import imath
        from alembic3d import Abc, AbcCoreAbstract, AbcGeom
    except ImportError as exc:
        raise LoosefitInputError(
            path,
            "<format>",
            "the Alembic bindings installed (pip install 'loosefit[alembic]')",
            str(exc),
        ) from exc
    return imath, Abc, AbcCoreAbstract, AbcGeom


def _array(cls, values: np.ndarray):
    """A PyImath array (``V3fArray``, ``IntArray``, ...) holding a copy of ``values``."""
    out = cls(len(values))
    np.asarray(memoryview(out))[...] = values
    return out


def export_alembic(
    path: Path, meshes: list[AnimatedMesh], fps: float, config: ExportConfig | None = None
) -> list[Path]:
    """An Alembic archive of every mesh as a point cache (see the module's notes)."""
    config = config or ExportConfig()
    imath, Abc, AbcCoreAbstract, AbcGeom = _alembic(path)
    T = check_meshes(meshes, fps, path)
    rotation = None if config.up_axis == "Z" else Z_TO_Y_UP.astype(np.float32)
    scope = AbcGeom.GeometryScope
    with atomic_path(path) as tmp:
        archive = Abc.OArchive(str(tmp))  # Ogawa
        sampling = archive.addTimeSampling(AbcCoreAbstract.TimeSampling(1.0 / fps, 0.0))
        schemas = []
        for m in meshes:
            mesh = AbcGeom.OPolyMesh(archive.getTop(), m.name, sampling)
            schemas.append(mesh.getSchema())
        for t in range(T):
            for m, schema in zip(meshes, schemas, strict=True):
                v = m.vertices[t] if rotation is None else m.vertices[t] @ rotation.T
                sample = AbcGeom.OPolyMeshSchemaSample()
                keep = [_array(imath.V3fArray, v)]  # alive until the sample is written
                sample.setPositions(keep[0])
                if t == 0:  # topology and UVs once: constant after the first sample
                    keep += [
                        _array(imath.IntArray, m.faces[:, ::-1].ravel()),
                        _array(imath.IntArray, np.full(len(m.faces), 3)),
                    ]
                    sample.setFaceIndices(keep[-2])
                    sample.setFaceCounts(keep[-1])
                    if m.uvs is not None:
                        keep += [
                            _array(imath.V2fArray, m.uvs),
                            imath.UnsignedIntArray(  # (no buffer of its own: by doubles)
                                _array(imath.DoubleArray, m.face_uvs[:, ::-1].ravel())
                            ),
                        ]
                        keep.append(
                            AbcGeom.OV2fGeomParamSample(keep[-2], keep[-1], scope.kFacevaryingScope)
                        )
                        sample.setUVs(keep[-1])
                if m.normals:
                    keep.append(_array(imath.V3fArray, vertex_normals_np(v, m.faces)))
                    keep.append(AbcGeom.ON3fGeomParamSample(keep[-1], scope.kVertexScope))
                    sample.setNormals(keep[-1])
                schema.set(sample)
        del schemas, mesh, archive  # the archive is complete when the last reference goes
    return [path]
