"""Animated meshes to the formats artists' tools read, chosen by the file's suffix.

Like trimesh's exporter table, :data:`EXPORTERS` maps a suffix to a writer:

* ``.usd`` / ``.usdc`` (binary crate) / ``.usda`` (text), through Pixar's ``usd-core``:
  one ``UsdGeom.Mesh`` per animated mesh under ``/loosefit``, its points
  time-sampled on every frame (frame t at time code t), UVs as the ``st``
  primvar (face-varying), the stage declaring Z up, metres
  (``metersPerUnit = 1``) and the frame rate (``timeCodesPerSecond``).
* ``.pc2``: a point cache (Blender's Mesh Cache modifier, Maya, Houdini, 3ds Max)
  of the first mesh, the others beside it as ``STEM_NAME.pc2``, and each mesh's
  first frame with its UVs as ``STEM[_NAME].obj`` to put the cache on (import it
  keeping the vertex order).
* a folder (no suffix): one OBJ per frame and mesh, ``NAME_000000.obj``.

Every file is written to a temporary name beside it and renamed when complete, so a
failed export leaves nothing that looks finished.

The PC2 layout (a 32-byte little-endian header, then float32 x, y, z per point per
sample)::

    char[12] "POINTCACHE2\\0"; int32 version = 1; int32 points;
    float32 start frame; float32 sample rate (frames between samples); int32 samples
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from loosefit.atomic import atomic_path
from loosefit.errors import LoosefitInputError

PC2_MAGIC = b"POINTCACHE2\0"
PC2_HEADER = struct.Struct("<12siiffi")


@dataclass
class AnimatedMesh:
    """A triangle mesh whose vertices move.

    Attributes:
        name: a label (a USD prim name and a file-name part: letters, digits, ``_``).
        faces: (F, 3) int vertex indices, counter-clockwise seen from outside.
        vertices: (T, V, 3) float32 positions, metres, Z up.
        uvs: (U, 2) UV coordinates and ``face_uvs`` (F, 3) indices into them, or None.
    """

    name: str
    faces: np.ndarray
    vertices: np.ndarray
    uvs: np.ndarray | None = None
    face_uvs: np.ndarray | None = None

    def __post_init__(self) -> None:
        src = f"mesh '{self.name}'"
        if not self.name.replace("_", "").isalnum() or self.name[0].isdigit():
            raise LoosefitInputError(
                src, "name", "letters, digits and _ (not first a digit)", repr(self.name)
            )
        v = np.asarray(self.vertices, np.float32)
        if v.ndim != 3 or v.shape[-1] != 3 or len(v) == 0:
            raise LoosefitInputError(src, "vertices", "shape (T >= 1, V, 3)", f"{v.shape}")
        if not np.isfinite(v).all():
            t = int(np.argwhere(~np.isfinite(v))[0][0])
            raise LoosefitInputError(src, "vertices", "finite values", f"NaN/inf in frame {t}")
        f = np.asarray(self.faces, np.int64)
        if f.ndim != 2 or f.shape[1] != 3 or (len(f) and (f.min() < 0 or f.max() >= v.shape[1])):
            raise LoosefitInputError(
                src, "faces", f"(F, 3) indices in [0, {v.shape[1]})", f"shape {f.shape}"
            )
        if (self.uvs is None) != (self.face_uvs is None):
            raise LoosefitInputError(src, "uvs, face_uvs", "both or neither", "only one")
        if self.uvs is not None:
            self.uvs = np.asarray(self.uvs, np.float32)
            self.face_uvs = np.asarray(self.face_uvs, np.int64)
            if self.face_uvs.shape != f.shape or self.face_uvs.max() >= len(self.uvs):
                want = f"shape {f.shape}, indices < {len(self.uvs)}"
                raise LoosefitInputError(src, "face_uvs", want, f"shape {self.face_uvs.shape}")
        self.vertices, self.faces = v, f

    @property
    def num_frames(self) -> int:
        return int(self.vertices.shape[0])


def _check_meshes(meshes: list[AnimatedMesh], fps: float, where) -> int:
    if not meshes:
        raise LoosefitInputError(where, "meshes", "at least one animated mesh", "none")
    T = meshes[0].num_frames
    if any(m.num_frames != T for m in meshes):
        raise LoosefitInputError(
            where, "meshes", f"{T} frames each", str([m.num_frames for m in meshes])
        )
    if len({m.name for m in meshes}) != len(meshes):
        raise LoosefitInputError(where, "meshes", "distinct names", [m.name for m in meshes])
    if not (np.isfinite(fps) and fps > 0):
        raise LoosefitInputError(where, "fps", "a positive frame rate", fps)
    return T


# -- PC2 ---------------------------------------------------------------------------------------


def write_pc2(path: str | Path, vertices: np.ndarray, start_frame: float = 0.0) -> Path:
    """One point cache: (T, V, 3) positions, a sample every frame from ``start_frame``."""
    v = np.ascontiguousarray(vertices, "<f4")
    T, V = v.shape[:2]
    with atomic_path(Path(path)) as tmp, open(tmp, "wb") as fh:
        fh.write(PC2_HEADER.pack(PC2_MAGIC, 1, V, float(start_frame), 1.0, T))
        fh.write(v.tobytes())
    return Path(path)


def read_pc2(path: str | Path) -> tuple[np.ndarray, float, float]:
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
    return v.astype(np.float32), float(start), float(rate)


def _obj_of(path: Path, mesh: AnimatedMesh, frame: int) -> None:
    from loosefit.garment.obj import write_obj

    write_obj(path, mesh.vertices[frame], mesh.faces, mesh.uvs, mesh.face_uvs)


def export_pc2(path: Path, meshes: list[AnimatedMesh], fps: float) -> list[Path]:
    """The first mesh's cache at ``path``, the others as ``STEM_NAME.pc2``; an OBJ of each."""
    _check_meshes(meshes, fps, path)
    written = []
    for i, m in enumerate(meshes):
        stem = path.stem if i == 0 else f"{path.stem}_{m.name}"
        cache, obj = path.with_name(stem + ".pc2"), path.with_name(stem + ".obj")
        written += [write_pc2(cache, m.vertices), obj]
        _obj_of(obj, m, 0)
    return written


# -- OBJ sequence --------------------------------------------------------------------------------


def export_obj_sequence(folder: Path, meshes: list[AnimatedMesh], fps: float) -> list[Path]:
    """``folder/NAME_000000.obj`` ... one OBJ per frame and mesh (each written atomically)."""
    T = _check_meshes(meshes, fps, folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for m in meshes:
        for t in range(T):
            written.append(folder / f"{m.name}_{t:06d}.obj")
            _obj_of(written[-1], m, t)
    return written


# -- USD -------------------------------------------------------------------------------------------


def export_usd(path: Path, meshes: list[AnimatedMesh], fps: float) -> list[Path]:
    """A USD stage (format by suffix) with every mesh's points time-sampled."""
    try:
        from pxr import Gf, Sdf, Usd, UsdGeom, Vt
    except ImportError as exc:  # a dependency of loosefit; a clear message if it is missing
        raise LoosefitInputError(
            path, "<format>", "usd-core installed (pip install usd-core)", str(exc)
        ) from exc
    T = _check_meshes(meshes, fps, path)
    with atomic_path(path) as tmp:
        stage = Usd.Stage.CreateNew(str(tmp))
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
        UsdGeom.SetStageMetersPerUnit(stage, 1.0)
        stage.SetTimeCodesPerSecond(float(fps))
        stage.SetFramesPerSecond(float(fps))
        stage.SetStartTimeCode(0)
        stage.SetEndTimeCode(T - 1)
        root = UsdGeom.Xform.Define(stage, "/loosefit")
        stage.SetDefaultPrim(root.GetPrim())
        for m in meshes:
            mesh = UsdGeom.Mesh.Define(stage, f"/loosefit/{m.name}")
            mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
            mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(m.faces)))
            mesh.CreateFaceVertexIndicesAttr(
                Vt.IntArray.FromNumpy(m.faces.astype(np.int32).ravel())
            )
            points, extent = mesh.CreatePointsAttr(), mesh.CreateExtentAttr()
            for t in range(T):
                v = m.vertices[t]
                points.Set(Vt.Vec3fArray.FromNumpy(v), Usd.TimeCode(t))
                lo, hi = v.min(0).tolist(), v.max(0).tolist()
                extent.Set(Vt.Vec3fArray([Gf.Vec3f(*lo), Gf.Vec3f(*hi)]), Usd.TimeCode(t))
            if m.uvs is not None:
                st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(
                    "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying
                )
                st.Set(Vt.Vec2fArray.FromNumpy(m.uvs))
                st.SetIndices(Vt.IntArray.FromNumpy(m.face_uvs.astype(np.int32).ravel()))
        stage.GetRootLayer().Save()
        del stage
    return [path]


EXPORTERS: dict[str, Callable[[Path, list[AnimatedMesh], float], list[Path]]] = {
    ".usd": export_usd,
    ".usda": export_usd,
    ".usdc": export_usd,
    ".pc2": export_pc2,
    "": export_obj_sequence,
}


def export_animation(path: str | Path, meshes: list[AnimatedMesh], fps: float) -> list[Path]:
    """Write animated meshes in the format ``path``'s suffix names (:data:`EXPORTERS`).

    Args:
        path: the file (``.usd``, ``.usdc``, ``.usda``, ``.pc2``) or a folder (OBJ sequence).
        meshes: the meshes, the garment first; all with the same frames.
        fps: frames per second.

    Returns:
        The files written.

    Raises:
        LoosefitInputError: an unknown suffix, an unwritable folder or bad meshes.
    """
    path = check_export_path(path)
    return EXPORTERS[path.suffix.lower()](path, meshes, fps)


def check_export_path(path: str | Path) -> Path:
    """``path`` as a :func:`export_animation` target, checked before any work is done.

    Raises:
        LoosefitInputError: a suffix no exporter writes.
    """
    path = Path(path)
    if path.suffix.lower() not in EXPORTERS:
        known = ", ".join(s or "a folder (OBJ sequence)" for s in EXPORTERS)
        raise LoosefitInputError(path, "suffix", known, repr(path.suffix))
    return path


def garment_and_body(
    template, garment_vertices: np.ndarray, body_vertices=None, body_faces=None
) -> list[AnimatedMesh]:
    """The meshes of a dressed animation: the garment (with its UVs) and, if given, the body.

    Args:
        template: the garment's :class:`~loosefit.types.GarmentTemplate` (faces, UVs).
        garment_vertices: (T, V, 3) the garment's positions.
        body_vertices: (T, Vb, 3) the posed body, and ``body_faces`` (Fb, 3), or None.
    """
    meshes = [
        AnimatedMesh("garment", template.faces, garment_vertices, template.uvs, template.face_uvs)
    ]
    if body_vertices is not None:
        meshes.append(AnimatedMesh("body", np.asarray(body_faces), body_vertices))
    return meshes
