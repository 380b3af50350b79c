"""PC2 + OBJ and OBJ sequences: the PC2 read back from its spec, Y up by default (the OBJ
convention) in the OBJ's axes, loosefit's own axes on request, a mesh Blender's OBJ
importer would shorten, and a bad cache."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.export import AnimatedMesh, ExportConfig, export_animation, read_pc2
from loosefit.garment.obj import read_obj
from tests.export.rigged import dressed

# (x, y, z) Y up -> loosefit's Z up: (x, -z, y)
Y_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def _obj_vertices_and_name(path):
    lines = path.read_text().splitlines()
    v = np.array([[float(x) for x in ln.split()[1:]] for ln in lines if ln.startswith("v ")])
    names = [ln.split()[1] for ln in lines if ln.startswith("o ")]
    return v, names


@pytest.mark.parametrize("up", [None, "Y", "Z"])
def test_pc2_and_its_obj_share_the_axes_y_up_by_default(tmp_path, up):
    meshes = dressed(T=3)
    written = export_animation(tmp_path / "a.pc2", meshes, 30.0, ExportConfig(up_axis=up))
    names = ["a.pc2", "a.obj", "a_body.pc2", "a_body.obj"]
    assert written == [tmp_path / n for n in names]
    to_z = np.eye(3) if up == "Z" else Y_TO_Z_UP
    for m, stem in zip(meshes, ("a", "a_body"), strict=True):
        cache, start, rate = read_pc2(tmp_path / f"{stem}.pc2")
        assert (start, rate) == (0.0, 1.0)
        raw = (tmp_path / f"{stem}.pc2").read_bytes()  # the layout, read from the spec
        assert struct.unpack_from("<12siiffi", raw) == (
            b"POINTCACHE2\0",
            1,
            m.vertices.shape[1],
            0.0,
            1.0,
            3,
        )
        np.testing.assert_array_equal(np.frombuffer(raw, "<f4", offset=32).reshape(3, -1, 3), cache)
        np.testing.assert_array_equal(cache @ to_z.T, m.vertices)  # exact: a permutation
        obj, objects = _obj_vertices_and_name(tmp_path / f"{stem}.obj")
        assert objects == [m.name]
        np.testing.assert_array_equal(obj.astype(np.float32), cache[0])  # to the bit
        again = read_obj(tmp_path / f"{stem}.obj", compute_uvs_if_missing=False)
        np.testing.assert_array_equal(again.faces, m.faces)  # loosefit's vertex order
    if up != "Z":  # upright in Y: the body (0.7 to 1.3 m tall) is high in y, thin in z
        body = read_pc2(tmp_path / "a_body.pc2")[0]
        assert body[..., 1].min() > 0.6 and np.ptp(body[..., 2]) < 0.5


def test_a_cache_shorter_than_its_header_is_a_clear_error(tmp_path):
    bad = tmp_path / "bad.pc2"
    bad.write_bytes(b"POINTCACHE2\0" + b"\0" * 10)
    with pytest.raises(LoosefitInputError, match=r"bad\.pc2.*header"):
        read_pc2(bad)


def test_obj_sequence_is_a_file_per_frame_and_mesh_y_up_unless_asked(tmp_path):
    meshes = dressed(T=2)
    assert len(export_animation(tmp_path / "y", meshes, 30.0)) == 2 * 2
    export_animation(tmp_path / "z", meshes, 30.0, ExportConfig(up_axis="Z"))
    for folder, to_z in (("y", Y_TO_Z_UP), ("z", np.eye(3))):
        v, objects = _obj_vertices_and_name(tmp_path / folder / "garment_000001.obj")
        assert objects == ["garment"]
        np.testing.assert_allclose(v @ to_z.T, meshes[0].vertices[1], atol=1e-7)


def test_a_vertex_in_no_face_is_written_with_a_warning(tmp_path):
    g = dressed(T=2)[0]
    extra = np.concatenate([g.vertices, g.vertices[:, :1]], axis=1)  # one more, unused
    lonely = AnimatedMesh("garment", g.faces, extra)
    with pytest.warns(UserWarning, match=r"1 of the 26 vertices of 'garment'.*Mesh Cache"):
        export_animation(tmp_path / "l.pc2", [lonely], 30.0)
    assert read_pc2(tmp_path / "l.pc2")[0].shape == (2, 26, 3)
