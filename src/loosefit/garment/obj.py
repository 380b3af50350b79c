"""Wavefront OBJ: read and write triangle meshes with UVs, and load a user's garment.

Supported: ``v`` (extra numbers such as vertex colours ignored), ``vt``, ``vn``
(read and ignored), ``f`` with corners ``v``, ``v/vt``, ``v//vn`` or
``v/vt/vn``, 1-based or negative (relative) indices, polygons (split into a
fan of triangles) and ``#`` comments. ``o``, ``g``, ``s``, ``usemtl``,
``mtllib``, ``l``, ``p`` and any other keyword are ignored. Every problem is
raised as a :class:`~loosefit.errors.LoosefitInputError` naming the file, the
field (with its line number where there is one), what was expected and found.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from loosefit.atomic import atomic_path
from loosefit.errors import LoosefitInputError
from loosefit.garment.mesh_checks import (
    boundary_loops,
    degenerate_faces,
    nonmanifold_edges,
    uv_charts,
    uv_triangle_areas,
)
from loosefit.types import GarmentTemplate


@dataclass
class ObjMesh:
    """A triangle mesh read from an OBJ file.

    Attributes:
        vertices: (V, 3) float32 positions.
        faces: (F, 3) int64 vertex indices (0-based), polygons split into fans.
        uvs: (U, 2) float32 UV coordinates, or None.
        face_uvs: (F, 3) int64 indices into ``uvs`` per face corner, or None.
        face_lines: (F,) int64 line number (1-based) of the ``f`` line each triangle
            came from; None when the mesh did not come from a file.
    """

    vertices: np.ndarray
    faces: np.ndarray
    uvs: np.ndarray | None = None
    face_uvs: np.ndarray | None = None
    face_lines: np.ndarray | None = None


# ---------------------------------------------------------------------------------------------
# Reading


def _floats(path: Path, keyword: str, line_no: int, fields: list[str], count: int) -> list[float]:
    """The first ``count`` numbers of a ``v``/``vt`` line (missing trailing ones are 0)."""
    minimum = 3 if keyword == "v" else 1
    if len(fields) < minimum:
        raise LoosefitInputError(
            path, f"{keyword} (line {line_no})", f"at least {minimum} numbers", f"{len(fields)}"
        )
    try:
        values = [float(x) for x in fields[:count]]
    except ValueError as exc:
        raise LoosefitInputError(
            path, f"{keyword} (line {line_no})", "numbers", repr(" ".join(fields))
        ) from exc
    return values + [0.0] * (count - len(values))


def _resolve(path: Path, line_no: int, token: str, what: str, index: str, defined: int) -> int:
    """A 0-based index from an OBJ index token (1-based, or negative = relative to ``defined``)."""
    try:
        k = int(index)
    except ValueError as exc:
        raise LoosefitInputError(
            path, f"f (line {line_no})", f"integer {what} indices", repr(token)
        ) from exc
    if k == 0:
        raise LoosefitInputError(
            path, f"f (line {line_no})", f"{what} indices from 1 (or negative)", repr(token)
        )
    if k < 0 and defined + k < 0:
        raise LoosefitInputError(
            path,
            f"f (line {line_no})",
            f"relative {what} indices within the {defined} defined so far",
            repr(token),
        )
    return k - 1 if k > 0 else defined + k


@dataclass
class _ObjRecords:
    """What an OBJ file's lines hold, indices resolved, before the mesh checks.

    Attributes:
        vertices: V ``v`` coordinates (3 each); ``vertex_lines`` their line numbers.
        uvs: U ``vt`` coordinates (2 each); ``uv_lines`` their line numbers.
        faces: F triangles (0-based vertex indices), polygons split into fans.
        face_uvs: F triangles' 0-based ``vt`` indices, or None for a face without.
        face_lines: F line numbers of the ``f`` line each triangle came from.
    """

    vertices: list[list[float]]
    vertex_lines: list[int]
    uvs: list[list[float]]
    uv_lines: list[int]
    faces: list[list[int]]
    face_uvs: list[list[int] | None]
    face_lines: list[int]


def _face_corners(
    path: Path, line_no: int, raw: str, args: list[str], n_vertices: int, n_uvs: int
) -> tuple[list[int], list[int | None]]:
    """An ``f`` line's corners: 0-based vertex indices and ``vt`` indices (or None)."""
    if len(args) < 3:
        raise LoosefitInputError(path, f"f (line {line_no})", "at least 3 corners", f"{len(args)}")
    corners, corner_uvs = [], []
    for token in args:
        parts = token.split("/")
        if len(parts) > 3 or parts[0] == "":
            raise LoosefitInputError(
                path,
                f"f (line {line_no})",
                "corners v, v/vt, v//vn or v/vt/vn",
                repr(token),
            )
        corners.append(_resolve(path, line_no, token, "vertex", parts[0], n_vertices))
        has_uv = len(parts) > 1 and parts[1] != ""
        corner_uvs.append(_resolve(path, line_no, token, "vt", parts[1], n_uvs) if has_uv else None)
    if any(c is None for c in corner_uvs) and not all(c is None for c in corner_uvs):
        raise LoosefitInputError(
            path,
            f"f (line {line_no})",
            "UV indices on every corner or on none",
            repr(raw.strip()),
        )
    return corners, corner_uvs


def _parse_obj(path: Path, text: str) -> _ObjRecords:
    """The ``v``, ``vt`` and ``f`` lines of an OBJ text; faces split into fans."""
    rec = _ObjRecords([], [], [], [], [], [], [])
    for line_no, raw in enumerate(text.splitlines(), start=1):
        fields = raw.split("#", 1)[0].split()
        if not fields:
            continue
        keyword, args = fields[0], fields[1:]
        if keyword == "v":
            rec.vertices.append(_floats(path, "v", line_no, args, 3))
            rec.vertex_lines.append(line_no)
        elif keyword == "vt":
            rec.uvs.append(_floats(path, "vt", line_no, args, 2))
            rec.uv_lines.append(line_no)
        elif keyword == "f":
            corners, corner_uvs = _face_corners(
                path, line_no, raw, args, len(rec.vertices), len(rec.uvs)
            )
            for k in range(1, len(corners) - 1):  # fan: (0, k, k + 1)
                rec.faces.append([corners[0], corners[k], corners[k + 1]])
                rec.face_uvs.append(
                    None
                    if corner_uvs[0] is None
                    else [corner_uvs[0], corner_uvs[k], corner_uvs[k + 1]]
                )
                rec.face_lines.append(line_no)
        # vn, o, g, s, usemtl, mtllib, l, p and unknown keywords are ignored
    return rec


def _checked_vertices(path: Path, rec: _ObjRecords) -> np.ndarray:
    """(V, 3) float64 vertex positions; an error names the first non-finite one."""
    verts = np.asarray(rec.vertices, dtype=np.float64).reshape(-1, 3)
    with np.errstate(over="ignore"):  # beyond float32 is as unusable as NaN
        bad = ~np.isfinite(verts.astype(np.float32)).all(axis=1)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        raise LoosefitInputError(
            path,
            f"v (line {rec.vertex_lines[first]})",
            "finite coordinates",
            f"{int(bad.sum())} vertices with NaN/inf, first {verts[first].tolist()}",
        )
    return verts


def _check_face_indices(path: Path, tri: np.ndarray, lines: np.ndarray, V: int) -> None:
    """Every (F, 3) vertex index within the ``V`` vertices; the error names the line."""
    out = (tri < 0) | (tri >= V)
    if out.any():
        f = int(np.flatnonzero(out.any(axis=1))[0])
        raise LoosefitInputError(
            path,
            f"f (line {lines[f]})",
            f"vertex indices within the {V} vertices defined",
            f"index {int(tri[f][out[f]][0]) + 1}",
        )


def _file_uvs(
    path: Path, rec: _ObjRecords, lines: np.ndarray
) -> tuple[np.ndarray, np.ndarray] | None:
    """The file's (U, 2) float64 UVs and (F, 3) int64 face UV indices, None without.

    Raises:
        LoosefitInputError: UVs on some faces but not others, an index out of range,
            a non-finite UV.
    """
    with_uv = np.array([c is not None for c in rec.face_uvs])
    if with_uv.any() and not with_uv.all():
        first_without = int(lines[np.flatnonzero(~with_uv)[0]])
        raise LoosefitInputError(
            path,
            "f (vt)",
            "UV indices on every face or on none",
            f"{int(with_uv.sum())} triangles with and {int((~with_uv).sum())} without, "
            f"first without on line {first_without}",
        )
    if not with_uv.all():
        return None
    U = len(rec.uvs)
    face_uvs = np.asarray(rec.face_uvs, dtype=np.int64)
    out = (face_uvs < 0) | (face_uvs >= U)
    if out.any():
        f = int(np.flatnonzero(out.any(axis=1))[0])
        raise LoosefitInputError(
            path,
            f"f (line {lines[f]})",
            f"vt indices within the {U} UVs defined",
            f"index {int(face_uvs[f][out[f]][0]) + 1}",
        )
    uvs = np.asarray(rec.uvs, dtype=np.float64).reshape(-1, 2)
    with np.errstate(over="ignore"):
        bad = ~np.isfinite(uvs.astype(np.float32)).all(axis=1)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        raise LoosefitInputError(
            path, f"vt (line {rec.uv_lines[first]})", "finite UV coordinates", "NaN/inf"
        )
    return uvs, face_uvs


def read_obj(path: str | os.PathLike, *, compute_uvs_if_missing: bool = True) -> ObjMesh:
    """Read a polygon mesh from an OBJ file and triangulate it.

    Args:
        path: the ``.obj`` file.
        compute_uvs_if_missing: when no face has UV indices, compute a UV atlas with
            xatlas (:func:`compute_uv_atlas`); otherwise leave ``uvs`` None.

    Returns:
        The :class:`ObjMesh` (V vertices, F triangles), with ``face_lines``.

    Raises:
        LoosefitInputError: unreadable file, malformed numbers, no faces, NaN/inf
            coordinates, indices out of range, UVs on some faces but not others.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise LoosefitInputError(path, "<file>", "a readable OBJ file", str(exc)) from exc

    rec = _parse_obj(path, text)
    if not rec.faces:
        raise LoosefitInputError(path, "f", "at least one face", "none")
    verts = _checked_vertices(path, rec)  # (V, 3)
    tri = np.asarray(rec.faces, dtype=np.int64)  # (F, 3)
    lines = np.asarray(rec.face_lines, dtype=np.int64)  # (F,)
    _check_face_indices(path, tri, lines, len(rec.vertices))

    mesh_uvs = mesh_face_uvs = None
    file_uvs = _file_uvs(path, rec, lines)
    if file_uvs is not None:
        mesh_uvs, mesh_face_uvs = file_uvs
    elif compute_uvs_if_missing:
        mesh_uvs, mesh_face_uvs = compute_uv_atlas(verts, tri)

    return ObjMesh(
        vertices=verts.astype(np.float32),
        faces=tri,
        uvs=None if mesh_uvs is None else mesh_uvs.astype(np.float32),
        face_uvs=mesh_face_uvs,
        face_lines=lines,
    )


# ---------------------------------------------------------------------------------------------
# Writing


def _check_write(
    vertices: np.ndarray,
    faces: np.ndarray,
    uvs: np.ndarray | None,
    face_uvs: np.ndarray | None,
) -> None:
    src = "write_obj"
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise LoosefitInputError(src, "vertices", "shape (V, 3)", f"shape {vertices.shape}")
    if not np.isfinite(vertices).all():
        raise LoosefitInputError(src, "vertices", "finite coordinates", "NaN or inf")
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise LoosefitInputError(src, "faces", "shape (F, 3)", f"shape {faces.shape}")
    if len(faces) and (faces.min() < 0 or faces.max() >= len(vertices)):
        raise LoosefitInputError(
            src, "faces", f"indices in [0, {len(vertices)})", f"[{faces.min()}, {faces.max()}]"
        )
    if (uvs is None) != (face_uvs is None):
        raise LoosefitInputError(src, "uvs, face_uvs", "both or neither", "only one")
    if uvs is not None and face_uvs is not None:
        if uvs.ndim != 2 or uvs.shape[1] != 2 or not np.isfinite(uvs).all():
            raise LoosefitInputError(src, "uvs", "finite, shape (U, 2)", f"shape {uvs.shape}")
        if face_uvs.shape != faces.shape:
            raise LoosefitInputError(
                src, "face_uvs", f"shape {faces.shape}", f"shape {face_uvs.shape}"
            )
        if len(face_uvs) and (face_uvs.min() < 0 or face_uvs.max() >= len(uvs)):
            raise LoosefitInputError(
                src,
                "face_uvs",
                f"indices in [0, {len(uvs)})",
                f"[{face_uvs.min()}, {face_uvs.max()}]",
            )


def write_obj(
    path: str | os.PathLike,
    vertices: np.ndarray,
    faces: np.ndarray,
    uvs: np.ndarray | None = None,
    face_uvs: np.ndarray | None = None,
    name: str | None = None,
) -> None:
    """Write a triangle mesh (and UVs) to an OBJ file, atomically.

    The text goes to a temporary file beside ``path`` that then replaces it, so
    a reader never sees a half-written file. Coordinates are written with 9
    significant digits (float32 round-trips exactly).

    Args:
        path: the ``.obj`` file to write.
        vertices: (V, 3) positions.
        faces: (F, 3) 0-based vertex indices.
        uvs: (U, 2) UV coordinates, or None.
        face_uvs: (F, 3) 0-based indices into ``uvs``, or None (with ``uvs``).
        name: the object's name (an ``o`` line: what an importer calls it), or None.
    """
    vertices = np.asarray(vertices)
    faces = np.asarray(faces, dtype=np.int64)
    uvs = None if uvs is None else np.asarray(uvs)
    face_uvs = None if face_uvs is None else np.asarray(face_uvs, dtype=np.int64)
    _check_write(vertices, faces, uvs, face_uvs)

    parts = ["# written by loosefit\n"] + ([f"o {name}\n"] if name else [])
    parts += [f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in vertices.tolist()]
    if uvs is not None and face_uvs is not None:
        parts += [f"vt {u:.9g} {v:.9g}\n" for u, v in uvs.tolist()]
        corners = np.stack([faces + 1, face_uvs + 1], axis=-1).tolist()  # (F, 3, 2)
        parts += [f"f {a[0]}/{a[1]} {b[0]}/{b[1]} {c[0]}/{c[1]}\n" for a, b, c in corners]
    else:
        parts += [f"f {a} {b} {c}\n" for a, b, c in (faces + 1).tolist()]

    with atomic_path(Path(path)) as tmp:
        tmp.write_text("".join(parts), encoding="utf-8")


# ---------------------------------------------------------------------------------------------
# UV atlas


def compute_uv_atlas(
    vertices: np.ndarray, faces: np.ndarray, *, resolution: int = 256, padding: int = 2
) -> tuple[np.ndarray, np.ndarray]:
    """A UV atlas from xatlas, indexed so that ``faces`` keep indexing the input vertices.

    xatlas cuts the mesh into charts, flattens and packs them; the packed atlas
    is stretched to fill [0, 1]^2. Charts that xatlas laid out mirrored are
    flipped back, so every UV triangle is counter-clockwise when its 3D
    triangle is.

    Args:
        vertices: (V, 3) positions.
        faces: (F, 3) vertex indices.
        resolution: texels of the atlas xatlas packs for (a UV map of this size).
        padding: texels left between charts at that resolution.

    Returns:
        uvs: (U, 2) float64 UVs in [0, 1].
        face_uvs: (F, 3) int64 indices into ``uvs``, face by face as ``faces``.
    """
    import xatlas  # imported here: only needed for meshes without UVs

    faces = np.asarray(faces, dtype=np.int64)
    atlas = xatlas.Atlas()
    atlas.add_mesh(np.ascontiguousarray(vertices, dtype=np.float32), faces.astype(np.uint32))
    pack = xatlas.PackOptions()
    pack.resolution = resolution
    pack.padding = padding
    atlas.generate(xatlas.ChartOptions(), pack)
    vmapping, indices, uvs = atlas[0]  # (U,), (F, 3), (U, 2)
    face_uvs = indices.astype(np.int64)
    assert face_uvs.shape == faces.shape and (vmapping[face_uvs] == faces).all()
    uvs = uvs.astype(np.float64)

    charts = uv_charts(face_uvs, len(uvs))  # (U,)
    area = uv_triangle_areas(uvs, face_uvs)  # (F,)
    chart_area = np.bincount(charts[face_uvs[:, 0]], weights=area, minlength=charts.max() + 1)
    for chart in np.flatnonzero(chart_area < 0):  # mirror u within the chart's own box
        members = charts == chart
        u = uvs[members, 0]
        uvs[members, 0] = u.min() + u.max() - u
    return np.clip(uvs, 0.0, 1.0), face_uvs


def normalize_uvs(uvs: np.ndarray, margin: float = 0.02, *, keep_aspect: bool = True) -> np.ndarray:
    """Map UVs affinely into [margin, 1 - margin]^2.

    Args:
        uvs: (U, 2) UV coordinates.
        margin: border left free on every side.
        keep_aspect: one scale for u and v (centred in the square); otherwise each
            axis is stretched to fill.

    Returns:
        (U, 2) float64 UVs.
    """
    uvs = np.asarray(uvs, dtype=np.float64)
    low, high = uvs.min(axis=0), uvs.max(axis=0)
    extent = np.maximum(high - low, 1e-12)  # (2,)
    size = 1.0 - 2.0 * margin
    if keep_aspect:
        scale = size / extent.max()
        offset = margin + 0.5 * (size - scale * extent)  # (2,) centre the layout
        return offset + (uvs - low) * scale
    return margin + (uvs - low) * (size / extent)


# ---------------------------------------------------------------------------------------------
# Garments


def _first_face(mesh: ObjMesh, f: int) -> str:
    line = "" if mesh.face_lines is None else f" (line {int(mesh.face_lines[f])})"
    corners = ", ".join(str(int(k) + 1) for k in mesh.faces[f])
    return f"triangle {f}{line} with vertices {corners} (1-based, as in the file)"


def garment_uvs(
    vertices: np.ndarray,
    faces: np.ndarray,
    uvs: np.ndarray | None,
    face_uvs: np.ndarray | None,
    margin: float = 0.02,
) -> tuple[np.ndarray, np.ndarray, str]:
    """A garment's UVs in the unit square: the file's (``uvs`` (U, 2), ``face_uvs`` (F, 3)),
    scaled into it (aspect kept) when they leave it, or an xatlas atlas when it has none.

    Returns:
        uvs, face_uvs, and where they came from: ``"file"``, ``"file, rescaled"`` or
        ``"xatlas"``.
    """
    if uvs is None or face_uvs is None:
        atlas, face_atlas = compute_uv_atlas(vertices, faces)
        return normalize_uvs(atlas, margin, keep_aspect=False), face_atlas, "xatlas"
    if (uvs < 0).any() or (uvs > 1).any():
        return normalize_uvs(uvs, margin), face_uvs, "file, rescaled"
    return uvs, face_uvs, "file"


def load_garment_obj(
    path: str | os.PathLike,
    *,
    waist: str | np.ndarray = "top",
    name: str | None = None,
    uv_margin: float = 0.02,
) -> GarmentTemplate:
    """Read a user's garment mesh, checking it and giving it UVs and a waistband.

    UVs: without UVs in the file, an xatlas atlas stretched into
    ``[uv_margin, 1 - uv_margin]^2``; the file's UVs are kept when they lie in
    the unit square and otherwise scaled (aspect kept) into it.

    Args:
        path: the ``.obj`` file (triangles or polygons; the surface wound
            counter-clockwise seen from outside).
        waist: ``"top"`` for the boundary loop with the highest mean z (the garment's
            top opening), or a (W,) array of vertex indices.
        name: the template's name; default: the file's stem.
        uv_margin: border of the UV square left free by computed or rescaled UVs.

    Returns:
        A :class:`GarmentTemplate`; ``meta`` records the source file and where the UVs
        came from (``"file"``, ``"file, rescaled"`` or ``"xatlas"``).

    Raises:
        LoosefitInputError: any problem :func:`read_obj` finds, zero-area triangles,
            edges shared by more than two triangles, no open top boundary, or bad
            waist indices.
    """
    path = Path(path)
    mesh = read_obj(path, compute_uvs_if_missing=False)
    degenerate = degenerate_faces(mesh.vertices, mesh.faces)
    if len(degenerate):
        raise LoosefitInputError(
            path,
            "f",
            "triangles with non-zero area",
            f"{len(degenerate)} zero-area triangles, first: {_first_face(mesh, degenerate[0])}",
        )
    nonmanifold = nonmanifold_edges(mesh.faces)
    if len(nonmanifold):
        a, b = (int(k) + 1 for k in nonmanifold[0])
        raise LoosefitInputError(
            path,
            "f",
            "each edge shared by at most 2 triangles",
            f"{len(nonmanifold)} non-manifold edges, first between vertices {a} and {b} "
            "(1-based, as in the file)",
        )

    uvs, face_uvs, uv_source = garment_uvs(
        mesh.vertices, mesh.faces, mesh.uvs, mesh.face_uvs, uv_margin
    )

    V = len(mesh.vertices)
    if isinstance(waist, str):
        if waist != "top":
            raise LoosefitInputError(path, "waist", "'top' or an index array", repr(waist))
        loops = boundary_loops(mesh.faces)
        if not loops:
            raise LoosefitInputError(
                path, "waist", "an open top boundary (the waistband)", "a closed surface"
            )
        heights = [float(mesh.vertices[loop, 2].mean()) for loop in loops]
        waist_idx = loops[int(np.argmax(heights))]
    else:
        waist_idx = np.asarray(waist)
        if waist_idx.ndim != 1 or len(waist_idx) == 0 or waist_idx.dtype.kind not in "iu":
            raise LoosefitInputError(
                path,
                "waist",
                "a non-empty 1-D integer index array",
                f"shape {waist_idx.shape}, dtype {waist_idx.dtype}",
            )
        if waist_idx.min() < 0 or waist_idx.max() >= V:
            raise LoosefitInputError(
                path,
                "waist",
                f"vertex indices in [0, {V})",
                f"range [{waist_idx.min()}, {waist_idx.max()}]",
            )

    flipped = int((uv_triangle_areas(uvs, face_uvs) < 0).sum())
    return GarmentTemplate(
        vertices=mesh.vertices,
        faces=mesh.faces,
        uvs=uvs,
        face_uvs=face_uvs,
        waist=waist_idx,
        name=path.stem if name is None else name,
        meta={"source": str(path), "uv_source": uv_source, "flipped_uv_faces": flipped},
    )
