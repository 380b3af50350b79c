"""OBJ reading/writing, garment import (checks, xatlas UVs, waistband) and the mesh checks."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.garment.mesh_checks import (
    boundary_loops,
    degenerate_faces,
    nonmanifold_edges,
    triangle_areas,
    unique_edges,
    uv_triangle_areas,
)
from loosefit.garment.obj import load_garment_obj, normalize_uvs, read_obj, write_obj
from loosefit.garment.skirt import SkirtConfig, make_skirt
from loosefit.garment.waist_fit import WaistFit


@pytest.fixture(scope="module")
def skirt():
    fit = WaistFit(center=[0.0, 0.0, 1.0], radii=[0.16, 0.11], height=1.0)
    return make_skirt(SkirtConfig(style="aline", rings=10, segments=24), fit)


def write(tmp_path: Path, text: str, name: str = "garment.obj") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# --- reading and writing -----------------------------------------------------------------------


def test_round_trip_with_uvs(tmp_path: Path, skirt) -> None:
    path = tmp_path / "skirt.obj"
    write_obj(path, skirt.vertices, skirt.faces, skirt.uvs, skirt.face_uvs)
    mesh = read_obj(path)
    np.testing.assert_array_equal(mesh.vertices, skirt.vertices)  # float32 written with 9 digits
    np.testing.assert_array_equal(mesh.faces, skirt.faces)
    np.testing.assert_array_equal(mesh.uvs, skirt.uvs)
    np.testing.assert_array_equal(mesh.face_uvs, skirt.face_uvs)
    assert mesh.vertices.dtype == np.float32 and mesh.faces.dtype == np.int64
    assert [p.name for p in tmp_path.iterdir()] == ["skirt.obj"]  # no temporary file left


def test_round_trip_without_uvs(tmp_path: Path, skirt) -> None:
    path = tmp_path / "plain.obj"
    write_obj(path, skirt.vertices, skirt.faces)
    mesh = read_obj(path, compute_uvs_if_missing=False)
    np.testing.assert_array_equal(mesh.vertices, skirt.vertices)
    np.testing.assert_array_equal(mesh.faces, skirt.faces)
    assert mesh.uvs is None and mesh.face_uvs is None


def test_write_replaces_an_existing_file(tmp_path: Path, skirt) -> None:
    path = write(tmp_path, "old contents\n", "skirt.obj")
    write_obj(path, skirt.vertices, skirt.faces)
    assert path.read_text().startswith("# written by loosefit")


def test_write_rejects_bad_arrays(tmp_path: Path, skirt) -> None:
    with pytest.raises(LoosefitInputError, match="face_uvs"):
        write_obj(tmp_path / "x.obj", skirt.vertices, skirt.faces, uvs=skirt.uvs)
    with pytest.raises(LoosefitInputError, match="faces"):
        write_obj(tmp_path / "x.obj", skirt.vertices, skirt.faces + skirt.num_vertices)
    assert not list(tmp_path.iterdir())


SQUARE = """# a unit square as one quad and a pentagon fan
mtllib garment.mtl
o square
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0.5 1.5 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vt 0.5 1
vn 0 0 1
g front
usemtl cloth
s off
"""


def test_quads_and_polygons_are_fanned(tmp_path: Path) -> None:
    path = write(tmp_path, SQUARE + "f 1 2 3 4\nf 4 3 5\n")
    mesh = read_obj(path, compute_uvs_if_missing=False)
    np.testing.assert_array_equal(mesh.faces, [[0, 1, 2], [0, 2, 3], [3, 2, 4]])
    np.testing.assert_array_equal(mesh.face_lines, [18, 18, 19])
    path = write(tmp_path, SQUARE + "f 1 2 3 5 4\n", "pentagon.obj")
    mesh = read_obj(path, compute_uvs_if_missing=False)
    np.testing.assert_array_equal(mesh.faces, [[0, 1, 2], [0, 2, 4], [0, 4, 3]])


@pytest.mark.parametrize(
    "face",
    ["f 1/1 2/2 3/3 4/4", "f 1/1/1 2/2/1 3/3/1 4/4/1", "f -5/-5 -4/-4 -3/-3 -2/-2"],
)
def test_corner_forms_and_negative_indices(tmp_path: Path, face: str) -> None:
    mesh = read_obj(write(tmp_path, SQUARE + face + "\n"))
    np.testing.assert_array_equal(mesh.faces, [[0, 1, 2], [0, 2, 3]])
    np.testing.assert_array_equal(mesh.face_uvs, [[0, 1, 2], [0, 2, 3]])
    np.testing.assert_allclose(mesh.uvs[mesh.face_uvs[1]], [[0, 0], [1, 1], [0, 1]])


def test_normal_only_corners_have_no_uvs(tmp_path: Path) -> None:
    mesh = read_obj(write(tmp_path, SQUARE + "f 1//1 2//1 3//1\n"), compute_uvs_if_missing=False)
    np.testing.assert_array_equal(mesh.faces, [[0, 1, 2]])
    assert mesh.uvs is None


def test_negative_indices_are_relative_to_the_line(tmp_path: Path) -> None:
    text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 1 1 0\nf -3 -1 -2\n"
    mesh = read_obj(write(tmp_path, text), compute_uvs_if_missing=False)
    np.testing.assert_array_equal(mesh.faces, [[0, 1, 2], [1, 3, 2]])


BAD_FILES = {
    "no_faces": ("v 0 0 0\nv 1 0 0\nv 0 1 0\n", "'f'", "at least one face"),
    "nan": ("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", "'v (line 2)'", "NaN"),
    "inf": ("v 0 0 0\nv 1 0 0\nv 0 inf 0\nf 1 2 3\n", "'v (line 3)'", "NaN/inf"),
    "face_range": ("v 0 0 0\nv 1 0 0\nv 0 1 0\n# c\nf 1 2 9\n", "'f (line 5)'", "index 9"),
    "relative_range": ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -7\n", "'f (line 4)'", "-7"),
    "zero_index": ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "'f (line 4)'", "from 1"),
    "not_a_number": ("v 0 0 0\nv 1 x 0\nv 0 1 0\nf 1 2 3\n", "'v (line 2)'", "numbers"),
    "bad_corner": ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 a 3\n", "'f (line 4)'", "'a'"),
    "two_corners": ("v 0 0 0\nv 1 0 0\nf 1 2\n", "'f (line 3)'", "3 corners"),
    "uv_range": (
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nf 1/1 2/2 3/3\n",
        "'f (line 6)'",
        "vt indices",
    ),
    "uv_mixed_faces": (
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\nf 2 4 3\n",
        "'f (vt)'",
        "first without on line 9",
    ),
    "uv_mixed_corners": (
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nf 1/1 2/2 3\n",
        "'f (line 6)'",
        "every corner",
    ),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_read_errors_name_the_file_and_field(tmp_path: Path, case: str) -> None:
    text, field, found = BAD_FILES[case]
    path = write(tmp_path, text, f"bad_{case}.obj")
    with pytest.raises(LoosefitInputError) as info:
        read_obj(path)
    message = str(info.value)
    assert f"bad_{case}.obj" in message and field in message and found in message
    with pytest.raises(LoosefitInputError):
        load_garment_obj(path)


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(LoosefitInputError, match="missing.obj"):
        read_obj(tmp_path / "missing.obj")


# --- garments ----------------------------------------------------------------------------------

STRIP = "v 0 0 1\nv 1 0 1\nv 0 0 0\nv 1 0 0\nv 2 0 1\nv 2 0 0\n"


def test_degenerate_triangles_are_reported(tmp_path: Path) -> None:
    text = STRIP + "f 3 4 2\nf 3 2 1\nf 1 2 5\nf 4 6 6\n"  # 1, 2, 5 collinear; 4, 6, 6 repeats
    path = write(tmp_path, text, "degenerate.obj")
    with pytest.raises(LoosefitInputError) as info:
        load_garment_obj(path)
    message = str(info.value)
    assert "degenerate.obj" in message and "'f'" in message
    assert "2 zero-area triangles" in message and "(line 9) with vertices 1, 2, 5" in message


def test_nonmanifold_edges_are_reported(tmp_path: Path) -> None:
    text = STRIP + "v 1 1 0.5\nv 1 -1 0.5\nf 1 3 2\nf 1 2 7\nf 2 1 8\n"  # edge 1-2 in 3 faces
    path = write(tmp_path, text, "fin.obj")
    with pytest.raises(LoosefitInputError) as info:
        load_garment_obj(path)
    message = str(info.value)
    assert "fin.obj" in message and "1 non-manifold edges" in message
    assert "vertices 1 and 2" in message


def test_closed_mesh_has_no_top_boundary(tmp_path: Path) -> None:
    text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 3 1 4\n"
    path = write(tmp_path, text, "tetra.obj")
    with pytest.raises(LoosefitInputError, match="tetra.obj: field 'waist'"):
        load_garment_obj(path)
    template = load_garment_obj(path, waist=np.array([0, 1, 2]))
    np.testing.assert_array_equal(template.waist, [0, 1, 2])
    with pytest.raises(LoosefitInputError, match="'waist'"):
        load_garment_obj(path, waist=np.array([0, 7]))


def test_load_skirt_finds_the_waist_ring(tmp_path: Path, skirt) -> None:
    path = tmp_path / "my_skirt.obj"
    write_obj(path, skirt.vertices, skirt.faces, skirt.uvs, skirt.face_uvs)
    template = load_garment_obj(path)
    assert template.name == "my_skirt" and template.meta["uv_source"] == "file"
    assert sorted(template.waist.tolist()) == sorted(skirt.waist.tolist())
    np.testing.assert_array_equal(template.uvs, skirt.uvs)
    assert load_garment_obj(path, name="other").name == "other"


def test_xatlas_uvs_for_a_mesh_without_uvs(tmp_path: Path, skirt) -> None:
    path = tmp_path / "no_uvs.obj"
    write_obj(path, skirt.vertices, skirt.faces)
    template = load_garment_obj(path)
    assert template.meta["uv_source"] == "xatlas"
    np.testing.assert_array_equal(template.faces, skirt.faces)  # still the file's vertices
    np.testing.assert_array_equal(template.vertices, skirt.vertices)
    assert template.face_uvs.shape == template.faces.shape
    assert template.uvs.min() >= 0.02 - 1e-6 and template.uvs.max() <= 0.98 + 1e-6
    assert (uv_triangle_areas(template.uvs, template.face_uvs) > 0).all()
    assert template.meta["flipped_uv_faces"] == 0
    # a vertex's UVs are its corners' UVs: each UV belongs to exactly one vertex
    owner = np.full(len(template.uvs), -1)
    owner[template.face_uvs.reshape(-1)] = template.faces.reshape(-1)
    pairs = np.unique(np.stack([template.face_uvs.reshape(-1), template.faces.reshape(-1)]), axis=1)
    assert len(np.unique(pairs[0])) == pairs.shape[1]
    assert sorted(template.waist.tolist()) == sorted(skirt.waist.tolist())
    # read_obj computes the same kind of atlas by default
    mesh = read_obj(path)
    assert mesh.uvs is not None and mesh.face_uvs.shape == mesh.faces.shape


def test_out_of_range_uvs_are_rescaled(tmp_path: Path) -> None:
    text = SQUARE.replace("vt 1 1", "vt 2 3") + "f 1/1 2/2 3/3 4/4\n"
    template = load_garment_obj(write(tmp_path, text), waist=np.array([2, 3]))
    assert template.meta["uv_source"] == "file, rescaled"
    assert template.uvs.min() >= 0.02 - 1e-6 and template.uvs.max() <= 0.98 + 1e-6


def test_normalize_uvs() -> None:
    uvs = np.array([[-1.0, 0.0], [3.0, 0.0], [3.0, 2.0]])
    kept = normalize_uvs(uvs, 0.1)
    np.testing.assert_allclose(kept[:, 0], [0.1, 0.9, 0.9])
    np.testing.assert_allclose(kept[:, 1], [0.3, 0.3, 0.7])  # aspect kept, centred
    filled = normalize_uvs(uvs, 0.1, keep_aspect=False)
    np.testing.assert_allclose(filled[:, 1], [0.1, 0.1, 0.9])


# --- mesh checks against naive loops -----------------------------------------------------------


def test_checks_match_naive_loops(skirt) -> None:
    faces, verts = skirt.faces, skirt.vertices.astype(np.float64)
    areas = [
        0.5 * np.linalg.norm(np.cross(verts[b] - verts[a], verts[c] - verts[a]))
        for a, b, c in faces
    ]
    np.testing.assert_allclose(triangle_areas(verts, faces), areas)
    uv = skirt.uvs.astype(np.float64)
    signed = []
    for a, b, c in skirt.face_uvs:
        (x1, y1), (x2, y2) = uv[b] - uv[a], uv[c] - uv[a]
        signed.append(0.5 * (x1 * y2 - x2 * y1))
    np.testing.assert_allclose(uv_triangle_areas(uv, skirt.face_uvs), signed)
    counts: dict[tuple[int, int], int] = {}
    for face in faces.tolist():
        for k in range(3):
            edge = tuple(sorted((face[k], face[(k + 1) % 3])))
            counts[edge] = counts.get(edge, 0) + 1
    edges, n = unique_edges(faces)
    assert {tuple(e): int(c) for e, c in zip(edges.tolist(), n, strict=True)} == counts


def test_boundary_loops_follow_the_winding(skirt) -> None:
    loops = boundary_loops(skirt.faces)
    segments = skirt.meta["config"]["segments"]
    top = next(loop for loop in loops if loop.min() == 0)
    assert sorted(top.tolist()) == list(range(segments))
    # consecutive loop vertices are boundary edges of one face, in that face's order
    directed = {tuple(e) for e in skirt.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2).tolist()}
    assert all((int(a), int(b)) in directed for a, b in zip(top, np.roll(top, -1), strict=True))


def test_small_checks() -> None:
    faces = np.array([[0, 1, 2], [0, 2, 1], [0, 1, 3], [4, 4, 5]])
    verts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [2, 2, 2], [3, 3, 3.0]])
    np.testing.assert_array_equal(nonmanifold_edges(faces), [[0, 1]])
    np.testing.assert_array_equal(degenerate_faces(verts, faces), [3])
    assert boundary_loops(np.zeros((0, 3), dtype=np.int64)) == []
