"""Motion and GarmentTemplate: what they accept, what they refuse (naming the field, what was
expected and what was found), and their .npz files read back exactly."""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.types import GarmentTemplate, Motion, load_npz


def _motion(T: int = 4, J: int = 3) -> Motion:
    rot = np.tile(np.eye(3, dtype=np.float32), (T, J, 1, 1))
    c, s = np.cos(0.3), np.sin(0.3)
    rot[:, 1] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    root = np.stack([np.arange(T) * 0.1, np.zeros(T), np.full(T, 0.9)], 1)
    return Motion(("Hips", "Spine", "Head")[:J], rot, root, 30.0, "walk", {"source": "test"})


def _template() -> GarmentTemplate:
    v = np.array([[0, 0, 1], [1, 0, 1], [0, 1, 1], [1, 1, 0.5]], np.float64)
    return GarmentTemplate(
        vertices=v,
        faces=[[0, 1, 2], [1, 3, 2]],
        uvs=[[0, 0], [1, 0], [0, 1], [1, 1]],
        face_uvs=[[0, 1, 2], [1, 3, 2]],
        waist=[0, 1],
        name="square",
        meta={"kind": "skirt", "rings": np.int64(2)},
    )


def test_a_motion_s_frames_duration_and_slice():
    m = _motion(T=7)
    assert (m.num_frames, m.num_joints) == (7, 3) and m.duration == pytest.approx(0.2)
    assert m.rotations.dtype == np.float32 and m.root_translation.dtype == np.float32
    part = m.slice(2, 5)
    assert part.num_frames == 3 and part.name == "walk" and part.meta == m.meta
    np.testing.assert_array_equal(part.root_translation, m.root_translation[2:5])
    part.meta["x"] = 1
    assert "x" not in m.meta  # its own meta


@pytest.mark.parametrize(
    ("change", "field", "found"),
    [
        (dict(joint_names=()), "joint_names", "none"),
        (dict(joint_names=("Hips", "Hips", "Head")), "joint_names", r"duplicates \['Hips'\]"),
        (dict(rotations=np.zeros((4, 2, 3, 3))), "rotations", r"shape \(4, 2, 3, 3\)"),
        (dict(rotations=np.zeros((0, 3, 3, 3))), "rotations", "0 frames"),
        (dict(root_translation=np.zeros((5, 3))), "root_translation", r"shape \(5, 3\)"),
        (
            dict(rotations=2 * np.tile(np.eye(3), (4, 3, 1, 1))),
            "rotations",
            r"max \|R R\^T - I\| = 3",
        ),
        (dict(rotations=-np.tile(np.eye(3), (4, 3, 1, 1))), "rotations", "12 reflections"),
        (dict(fps=0.0), "fps", "0.0"),
    ],
)
def test_a_bad_motion_is_refused_naming_the_field(change, field, found):
    m = _motion()
    fields = dict(
        joint_names=m.joint_names,
        rotations=m.rotations,
        root_translation=m.root_translation,
        fps=30.0,
    )
    with pytest.raises(LoosefitInputError, match=rf"motion 'bad': field '{field}'.*found {found}"):
        Motion(**{**fields, **change}, name="bad")


def test_nan_is_refused_with_its_count_and_first_place():
    m = _motion()
    root = m.root_translation.copy()
    root[2, 1] = root[3, 0] = np.nan
    with pytest.raises(
        LoosefitInputError,
        match=r"expected finite values, found 2 NaN/inf values, first at \(2, 1\)",
    ):
        Motion(m.joint_names, m.rotations, root, 30.0)


def test_a_motion_file_reads_back_exactly_and_a_bad_one_names_the_file(tmp_path):
    m = _motion()
    m.save(tmp_path / "walk.npz")
    back = Motion.load(tmp_path / "walk.npz")
    assert back.joint_names == m.joint_names and back.fps == 30.0 and back.name == "walk"
    np.testing.assert_array_equal(back.rotations, m.rotations)
    np.testing.assert_array_equal(back.root_translation, m.root_translation)
    np.savez(
        tmp_path / "short.npz",
        joint_names=np.array(m.joint_names),
        rotations=m.rotations,
        root_translation=m.root_translation[:2],
        fps=30.0,
    )
    with pytest.raises(LoosefitInputError, match=r"short\.npz: field 'root_translation'"):
        Motion.load(tmp_path / "short.npz")
    np.savez(
        tmp_path / "nofps.npz",
        joint_names=np.array(m.joint_names),
        rotations=m.rotations,
        root_translation=m.root_translation,
    )
    with pytest.raises(
        LoosefitInputError, match=r"nofps\.npz: field 'fps': expected present, found missing"
    ):
        Motion.load(tmp_path / "nofps.npz")
    np.savez(
        tmp_path / "text.npz",
        joint_names=np.array(m.joint_names),
        rotations=m.rotations,
        root_translation=m.root_translation,
        fps=np.array("thirty"),
    )
    with pytest.raises(
        LoosefitInputError, match=r"text\.npz: field 'fps': expected one finite number"
    ):
        Motion.load(tmp_path / "text.npz")


def test_pickles_and_other_files_are_refused(tmp_path):
    np.savez(tmp_path / "obj.npz", a=np.array([{"x": 1}], dtype=object))
    with pytest.raises(LoosefitInputError, match=r"found a pickled object \(refused"):
        load_npz(tmp_path / "obj.npz", "a .npz file", ())
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(
        LoosefitInputError, match=r"junk\.npz: field '<file>': expected a \.npz file"
    ):
        load_npz(tmp_path / "junk.npz", "a .npz file", ())
    np.save(tmp_path / "one.npy", np.zeros(3))  # one array, not a file of named fields
    with pytest.raises(LoosefitInputError, match=r"one\.npy: field '<file>'.*a single array"):
        load_npz(tmp_path / "one.npy", "a .npz file", ())


def test_a_template_s_rest_shape_and_its_file(tmp_path):
    t = _template()
    assert t.num_vertices == 4 and t.vertices.dtype == np.float32 and t.faces.dtype == np.int64
    assert t.rest is t.vertices
    t.save(tmp_path / "t.npz")
    back = GarmentTemplate.load(tmp_path / "t.npz")
    for k in ("vertices", "faces", "uvs", "face_uvs", "waist"):
        np.testing.assert_array_equal(getattr(back, k), getattr(t, k), err_msg=k)
    assert back.name == "square" and back.meta == {"kind": "skirt", "rings": 2}
    assert back.rest_vertices is None
    stretched = GarmentTemplate(
        t.vertices, t.faces, t.uvs, t.face_uvs, t.waist, rest_vertices=t.vertices * 2
    )
    stretched.save(tmp_path / "s.npz")
    np.testing.assert_array_equal(GarmentTemplate.load(tmp_path / "s.npz").rest, t.vertices * 2)


@pytest.mark.parametrize(
    ("change", "field", "found"),
    [
        (dict(faces=[[0, 1, 4], [1, 3, 2]]), "faces", r"range \[0, 4\]"),
        (dict(faces=np.zeros((0, 3), int), face_uvs=np.zeros((0, 3), int)), "faces", "0 faces"),
        (dict(face_uvs=[[0, 1, 2]]), "face_uvs", r"shape \(1, 3\)"),
        (dict(waist=[0, 9]), "waist", r"range \[0, 9\]"),
        (dict(uvs=[[0, 0], [1, 0], [0, 1.5], [1, 1]]), "uvs", "range"),
        (dict(rest_vertices=np.zeros((3, 3))), "rest_vertices", r"shape \(3, 3\)"),
    ],
)
def test_a_bad_template_is_refused_naming_the_field(change, field, found):
    t = _template()
    fields = dict(vertices=t.vertices, faces=t.faces, uvs=t.uvs, face_uvs=t.face_uvs, waist=t.waist)
    with pytest.raises(LoosefitInputError, match=rf"garment 'g': field '{field}'.*found {found}"):
        GarmentTemplate(**{**fields, **change}, name="g")
