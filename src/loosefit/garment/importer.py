"""A garment file from another tool, made into loosefit's conventions: metres, Z up.

Garment tools write OBJ (or glTF/GLB) in their own units and axes: Marvelous Designer and
CLO in millimetres or centimetres with Y up, Blender in metres with Z up, glTF in metres
with Y up. :func:`read_garment_mesh` reads a file and checks it is one clean piece of
cloth; :func:`detect_units` and :func:`detect_up` guess what the file does not say, from
the garment's own shape, and :func:`to_z_up` converts. Placement on the body is
:func:`loosefit.fitting.place.import_garment`'s.

Every problem is a :class:`~loosefit.errors.LoosefitInputError` naming the file and what
was found.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.garment.mesh_checks import boundary_loops, degenerate_faces, nonmanifold_edges

# metres per unit of the file
UNITS: dict[str, float] = {"m": 1.0, "dm": 0.1, "cm": 0.01, "mm": 0.001, "in": 0.0254}
# the file's up axis: "z" (loosefit's, Blender's), "y" (glTF's, most garment tools'), or
# either pointing down ("-z", "-y": a garment modelled upside down)
UP_AXES = ("z", "y", "-z", "-y")
KINDS = ("skirt", "dress")

# A garment's plausible size in metres: height along the body (a mini skirt to a gown)
# and width across it (it must go round a waist; a circle skirt's hem spans ~2 m)
PLAUSIBLE_HEIGHT = (0.15, 1.6)
PLAUSIBLE_WIDTH = (0.2, 2.6)
TYPICAL_SIZE = (0.7, 0.5)  # height, width: what the unit guess prefers among plausible ones


@dataclass
class GarmentMesh:
    """A garment's triangles as read from a file (the file's units and axes).

    Attributes:
        vertices: (V, 3) float64 positions.
        faces: (F, 3) int64 triangles.
        uvs: (U, 2) float32 UVs per corner, or None.
        face_uvs: (F, 3) int64 indices into ``uvs``, or None.
        dropped_vertices: how many vertices no triangle used (removed).
        face_lines: (F,) the OBJ line of each triangle, or None.
    """

    vertices: np.ndarray
    faces: np.ndarray
    uvs: np.ndarray | None
    face_uvs: np.ndarray | None
    dropped_vertices: int = 0
    face_lines: np.ndarray | None = None


def _read_trimesh(path: Path) -> GarmentMesh:
    """A glTF/GLB (or anything else trimesh reads) as one mesh: every mesh of the scene with
    its node transform, concatenated."""
    import trimesh

    try:
        scene = trimesh.load(str(path), force="scene", process=False)
    except Exception as exc:  # noqa: BLE001 - trimesh raises many types for a bad file
        raise LoosefitInputError(path, "<file>", "a mesh trimesh can read", str(exc)) from exc
    try:
        meshes = [g for g in scene.dump(concatenate=False) if isinstance(g, trimesh.Trimesh)]
    except Exception as exc:  # noqa: BLE001 - a malformed scene fails in many ways
        raise LoosefitInputError(path, "scene", "meshes trimesh can read", str(exc)) from exc
    if not meshes:
        raise LoosefitInputError(path, "meshes", "at least one triangle mesh", "none")
    vertices, faces, uvs, offset = [], [], [], 0
    for m in meshes:
        vertices.append(np.asarray(m.vertices, np.float64))
        faces.append(np.asarray(m.faces, np.int64) + offset)
        uv = getattr(m.visual, "uv", None)
        uvs.append(None if uv is None or len(uv) != len(m.vertices) else np.asarray(uv))
        offset += len(m.vertices)
    have_uvs = all(u is not None for u in uvs)
    f = np.concatenate(faces)
    return GarmentMesh(
        np.concatenate(vertices),
        f,
        np.concatenate(uvs).astype(np.float32) if have_uvs else None,
        f.copy() if have_uvs else None,
    )


def read_garment_mesh(path: str | Path) -> GarmentMesh:
    """Read a garment file (``.obj``; ``.gltf``/``.glb`` through trimesh) and check that it
    is one clean piece of cloth.

    Vertices no triangle uses are dropped (exporters often leave some).

    Raises:
        LoosefitInputError: an unreadable or empty file, NaN/inf, zero-area triangles,
            edges shared by more than two triangles, or several disconnected pieces (with
            how many and how large).
    """
    from loosefit.garment.obj import read_obj

    path = Path(path)
    if not path.is_file():
        raise LoosefitInputError(path, "<file>", "a garment file", "no such file")
    suffix = path.suffix.lower()
    if suffix == ".obj":
        obj = read_obj(path, compute_uvs_if_missing=False)
        mesh = GarmentMesh(
            obj.vertices.astype(np.float64),
            obj.faces,
            obj.uvs,
            obj.face_uvs,
            face_lines=obj.face_lines,
        )
    elif suffix in (".gltf", ".glb"):
        mesh = _read_trimesh(path)
    else:
        raise LoosefitInputError(path, "suffix", ".obj, .gltf or .glb", repr(path.suffix))
    if len(mesh.faces) == 0 or len(mesh.vertices) == 0:
        raise LoosefitInputError(path, "faces", "a garment's triangles", "an empty mesh")
    if mesh.faces.ndim != 2 or mesh.faces.shape[1] != 3:
        raise LoosefitInputError(path, "faces", "triangles (F, 3)", f"shape {mesh.faces.shape}")
    out = (mesh.faces < 0) | (mesh.faces >= len(mesh.vertices))
    if out.any():
        f = int(np.flatnonzero(out.any(1))[0])
        raise LoosefitInputError(
            path,
            "faces",
            f"vertex indices below {len(mesh.vertices)}",
            f"triangle {f} with {mesh.faces[f].tolist()}",
        )
    if (
        mesh.face_uvs is not None
        and mesh.uvs is not None
        and ((mesh.face_uvs < 0) | (mesh.face_uvs >= len(mesh.uvs))).any()
    ):
        mesh.uvs = mesh.face_uvs = None  # UVs that do not fit: made again by xatlas
    if not np.isfinite(mesh.vertices).all():
        bad = np.flatnonzero(~np.isfinite(mesh.vertices).all(1))
        raise LoosefitInputError(
            path,
            "vertices",
            "finite coordinates",
            f"{len(bad)} vertices with NaN/inf, first {int(bad[0])}",
        )
    # drop what no triangle uses
    used = np.zeros(len(mesh.vertices), bool)
    used[mesh.faces.ravel()] = True
    if not used.all():
        remap = np.cumsum(used) - 1
        mesh.vertices, mesh.faces = mesh.vertices[used], remap[mesh.faces]
        mesh.dropped_vertices = int((~used).sum())
    degenerate = degenerate_faces(mesh.vertices, mesh.faces)
    if len(degenerate):
        first = _face(mesh, degenerate[0])
        raise LoosefitInputError(
            path,
            "faces",
            "triangles with non-zero area",
            f"{len(degenerate)} zero-area triangles, first {first}",
        )
    nonmanifold = nonmanifold_edges(mesh.faces)
    if len(nonmanifold):
        a, b = (int(k) for k in nonmanifold[0])
        raise LoosefitInputError(
            path,
            "faces",
            "a manifold surface (each edge shared by at most 2 triangles)",
            f"{len(nonmanifold)} non-manifold edges, first between vertices {a} and {b} (0-based)",
        )
    sizes = component_sizes(mesh.faces, len(mesh.vertices))
    if len(sizes) > 1:
        raise LoosefitInputError(
            path,
            "faces",
            "one connected piece of cloth",
            f"{len(sizes)} disconnected pieces of {', '.join(map(str, sizes[:8]))}"
            f"{' ...' if len(sizes) > 8 else ''} vertices",
            hint="sew the pieces together in the garment tool, or export the one piece",
        )
    return mesh


def _face(mesh: GarmentMesh, f: int) -> str:
    line = "" if mesh.face_lines is None else f" (line {int(mesh.face_lines[f])})"
    return f"triangle {int(f)}{line}, vertices {[int(k) for k in mesh.faces[f]]} (0-based)"


def component_sizes(faces: np.ndarray, num_vertices: int) -> list[int]:
    """Vertex counts of the connected pieces of a mesh, largest first."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    graph = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(num_vertices,) * 2)
    n, labels = connected_components(graph, directed=False)
    return sorted(np.bincount(labels, minlength=n).tolist(), reverse=True)


# -- axes and units ---------------------------------------------------------------------------


def to_z_up(vertices: np.ndarray, up: str) -> np.ndarray:
    """(V, 3) positions of a file whose up axis is ``up`` in loosefit's frame (Z up; a
    Y-up file's front, +Z, becomes -Y, where the avatar faces)."""
    x, y, z = np.asarray(vertices, np.float64).T
    if up == "z":
        return np.stack([x, y, z], 1)
    if up == "y":
        return np.stack([x, -z, y], 1)
    if up == "-z":
        return np.stack([x, -y, -z], 1)
    if up == "-y":
        return np.stack([x, z, -y], 1)
    raise LoosefitInputError("--up", "up", f"one of {UP_AXES}", repr(up))


def detect_up(vertices: np.ndarray, faces: np.ndarray, source: str | Path = "garment") -> str:
    """The file's up axis, from the garment's openings.

    A skirt's or a dress's openings (waist, hem, neck, armholes) are stacked along the
    body: their centres spread along the up axis, while each opening is flat across it.
    Of Y and Z, the axis along which the openings' centres spread most, relative to how
    thick the openings are along it, is up; the largest opening (the hem) is at the bottom.

    Raises:
        LoosefitInputError: fewer than two openings (nothing to tell the axis by).
    """
    loops = boundary_loops(faces)
    if len(loops) < 2:
        raise LoosefitInputError(
            source,
            "up",
            "a garment with openings (waist and hem) to tell its up axis by",
            f"{len(loops)} opening(s)",
            hint="say it with --up y or --up z",
        )
    v = np.asarray(vertices, np.float64)
    centres = np.array([v[loop].mean(0) for loop in loops])  # (L, 3)
    thickness = np.array([np.ptp(v[loop], axis=0) for loop in loops]).mean(0)  # (3,)
    score = {
        a: float(np.ptp(centres[:, k]) / (thickness[k] + 1e-9)) for a, k in (("y", 1), ("z", 2))
    }
    axis = max(score, key=score.get)
    k = 1 if axis == "y" else 2
    perimeters = [np.linalg.norm(np.roll(v[loop], -1, 0) - v[loop], axis=1).sum() for loop in loops]
    hem = int(np.argmax(perimeters))
    others = np.delete(centres[:, k], hem)
    return axis if centres[hem, k] <= others.mean() else f"-{axis}"


def detect_units(vertices: np.ndarray, source: str | Path = "garment") -> tuple[str, dict]:
    """The file's unit, from the garment's size (``vertices`` already Z up).

    Each unit of :data:`UNITS` gives the garment a height and a width in metres; the unit
    is the one that makes both plausible for clothing (:data:`PLAUSIBLE_HEIGHT`,
    :data:`PLAUSIBLE_WIDTH`), nearest a typical garment's size where several do.

    Returns:
        The unit and, per unit, the (height, width) in metres it would give.

    Raises:
        LoosefitInputError: no unit gives a plausible garment (it asks for ``--units``).
    """
    v = np.asarray(vertices, np.float64)
    height, width = float(np.ptp(v[:, 2])), float(max(np.ptp(v[:, 0]), np.ptp(v[:, 1])))
    sizes = {u: (height * s, width * s) for u, s in UNITS.items()}
    (h_lo, h_hi), (w_lo, w_hi) = PLAUSIBLE_HEIGHT, PLAUSIBLE_WIDTH
    plausible = {
        u: abs(math.log(max(h, 1e-9) / TYPICAL_SIZE[0]))
        + abs(math.log(max(w, 1e-9) / TYPICAL_SIZE[1]))
        for u, (h, w) in sizes.items()
        if h_lo <= h <= h_hi and w_lo <= w <= w_hi
    }
    if not plausible:
        raise LoosefitInputError(
            source,
            "units",
            f"a size that fits a person in one of {list(UNITS)}",
            f"a garment {height:.4g} high and {width:.4g} wide in the file's units "
            f"({', '.join(f'{h:.3g} m high in {u}' for u, (h, _) in sizes.items())})",
            hint="say the unit with --units (m, dm, cm, mm or in)",
        )
    return min(plausible, key=plausible.get), sizes


def top_opening(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray | None:
    """(n,) the garment's top opening (Z up): the highest boundary loop that goes round the
    garment's vertical axis (a skirt's waistband, a dress's neckline; not an armhole).
    None when no loop goes round it."""
    v = np.asarray(vertices, np.float64)
    axis = 0.5 * (v[:, :2].min(0) + v[:, :2].max(0))
    best, best_z = None, -np.inf
    for loop in boundary_loops(faces):
        xy = v[loop, :2] - axis
        angle = np.arctan2(xy[:, 1], xy[:, 0])
        turns = np.diff(np.unwrap(np.append(angle, angle[0])))
        if abs(turns.sum()) > np.pi and v[loop, 2].mean() > best_z:  # winds round the axis
            best, best_z = loop, float(v[loop, 2].mean())
    return best


def detect_kind(faces: np.ndarray) -> str:
    """``dress`` for a garment with more than two openings (neck, armholes or straps, hem),
    else ``skirt`` (waist and hem; a strapless dress says ``--kind dress``)."""
    return "dress" if len(boundary_loops(faces)) > 2 else "skirt"
