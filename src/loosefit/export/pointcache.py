"""Point caches: PC2 (+ an OBJ to put it on) and OBJ sequences.

Both are written Y up by default, the OBJ convention (``ExportConfig.up_axis`` "Z" keeps
loosefit's own axes): (x, y, z) -> (x, z, -y), the PC2 in the same axes as the OBJ beside
it. So Blender's OBJ importer with its defaults (forward -Z, up Y) stands the mesh up by
its object's rotation, and a Mesh Cache modifier on it with its defaults (format PC2;
forward +Y, up +Z: the cache in the object's own axes) plays the cache in place. The OBJ
names its object (``o NAME``) and keeps loosefit's vertex order; Blender's importer keeps
that order too but drops a vertex no face uses, after which the modifier refuses the
cache (its vertex count differs), so such a mesh is written with a warning.

The PC2 layout (a 32-byte little-endian header, then float32 x, y, z per point per
sample)::

    char[12] "POINTCACHE2\\0"; int32 version = 1; int32 points;
    float32 start frame; float32 sample rate (frames between samples); int32 samples
"""

from __future__ import annotations

import struct
import warnings
from pathlib import Path
from typing import NamedTuple

import numpy as np

from loosefit.atomic import atomic_path
from loosefit.errors import LoosefitInputError
from loosefit.export.meshes import AnimatedMesh, ExportConfig, check_meshes, in_up_axis

PC2_MAGIC = b"POINTCACHE2\0"
PC2_HEADER = struct.Struct("<12siiffi")


# -- PC2 ---------------------------------------------------------------------------------------


def write_pc2(path: str | Path, vertices: np.ndarray, start_frame: float = 0.0) -> Path:
    """One point cache: (T, V, 3) positions, a sample every frame from ``start_frame``."""
    v = np.ascontiguousarray(vertices, "<f4")
    T, V = v.shape[:2]
    with atomic_path(Path(path)) as tmp, open(tmp, "wb") as fh:
        fh.write(PC2_HEADER.pack(PC2_MAGIC, 1, V, float(start_frame), 1.0, T))
        fh.write(v.tobytes())
    return Path(path)


class PointCache(NamedTuple):
    """A point cache as :func:`read_pc2` reads it."""

    vertices: np.ndarray  # (T, V, 3) float32 positions
    start_frame: float  # the frame of the first sample
    sample_rate: float  # frames between samples


def read_pc2(path: str | Path) -> PointCache:
    """A point cache: (T, V, 3) float32 positions, the start frame and the sample rate.

    Raises:
        LoosefitInputError: not a PC2 file, or its size disagrees with its header.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise LoosefitInputError(path, "<file>", "a readable .pc2 file", str(exc)) from exc
    if len(data) < PC2_HEADER.size:
        raise LoosefitInputError(path, "header", f"{PC2_HEADER.size} bytes", f"{len(data)} bytes")
    magic, version, V, start, rate, T = PC2_HEADER.unpack_from(data)
    if magic != PC2_MAGIC or version != 1:
        raise LoosefitInputError(path, "header", "POINTCACHE2 version 1", f"{magic!r} v{version}")
    want = PC2_HEADER.size + 12 * V * T
    if len(data) != want:
        raise LoosefitInputError(
            path, "size", f"{want} bytes for {T} samples of {V} points", f"{len(data)} bytes"
        )
    v = np.frombuffer(data, "<f4", offset=PC2_HEADER.size).reshape(T, V, 3)
    for name, value in (("start frame", start), ("sample rate", rate)):
        if not np.isfinite(value):
            raise LoosefitInputError(path, name, "a finite number", repr(value))
    bad = ~np.isfinite(v)
    if bad.any():
        raise LoosefitInputError(
            path,
            "points",
            "finite positions",
            f"{int(bad.sum())} NaN/inf values, first at "
            f"{tuple(int(i) for i in np.argwhere(bad)[0])}",
        )
    return PointCache(v.astype(np.float32), float(start), float(rate))


def _obj_of(path: Path, mesh: AnimatedMesh, frame: int, up_axis: str) -> None:
    from loosefit.garment.obj import write_obj

    vertices = in_up_axis(mesh.vertices[frame], up_axis)
    write_obj(path, vertices, mesh.faces, mesh.uvs, mesh.face_uvs, name=mesh.name)


def _warn_unused_vertices(mesh: AnimatedMesh, where: Path) -> None:
    unused = int((np.bincount(mesh.faces.ravel(), minlength=mesh.vertices.shape[1]) == 0).sum())
    if unused:
        warnings.warn(
            f"{where}: {unused} of the {mesh.vertices.shape[1]} vertices of '{mesh.name}' are "
            "in no face: Blender's OBJ importer drops them, and its Mesh Cache modifier then "
            "refuses the cache (vertex count mismatch)",
            stacklevel=3,
        )


def export_pc2(
    path: Path, meshes: list[AnimatedMesh], fps: float, config: ExportConfig | None = None
) -> list[Path]:
    """The first mesh's cache at ``path``, the others as ``STEM_NAME.pc2``; an OBJ of each
    (its first frame) beside its cache, both Y up unless ``config.up_axis`` is "Z"."""
    check_meshes(meshes, fps, path)
    up_axis = (config or ExportConfig()).up_axis or "Y"
    written = []
    for i, m in enumerate(meshes):
        _warn_unused_vertices(m, path)
        stem = path.stem if i == 0 else f"{path.stem}_{m.name}"
        cache, obj = path.with_name(stem + ".pc2"), path.with_name(stem + ".obj")
        written += [write_pc2(cache, in_up_axis(m.vertices, up_axis)), obj]
        _obj_of(obj, m, 0, up_axis)
    return written


# -- OBJ sequence --------------------------------------------------------------------------------


def export_obj_sequence(
    folder: Path, meshes: list[AnimatedMesh], fps: float, config: ExportConfig | None = None
) -> list[Path]:
    """``folder/NAME_000000.obj`` ... one OBJ per frame and mesh (each written atomically),
    Y up unless ``config.up_axis`` is "Z"."""
    T = check_meshes(meshes, fps, folder)
    up_axis = (config or ExportConfig()).up_axis or "Y"
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for m in meshes:
        for t in range(T):
            written.append(folder / f"{m.name}_{t:06d}.obj")
            _obj_of(written[-1], m, t, up_axis)
    return written
