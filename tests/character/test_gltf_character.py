"""A character's skinned mesh and animation read from its glTF."""

from __future__ import annotations

import json

import numpy as np
import pytest

from loosefit.character import has_skinned_mesh, read_character
from loosefit.errors import LoosefitInputError
from loosefit.motion.gltf_file import read_document
from loosefit.motion.retarget import axis_change
from tests.motion.gltf_writer import write_document


def test_the_skin_poses_the_mesh_as_the_body_it_was_made_from(character):
    path, body, motion = character
    c = read_character(path, 30.0)
    assert c.num_vertices == body.rest_vertices.shape[0] and c.num_frames == motion.num_frames
    assert c.joint_names[0] == "mixamorig:Hips"
    C = axis_change("+y", "+z")  # glTF's axes to anny's
    first = c.posed(0, 1)[0] @ C.T
    want = body.pose_motion(motion.slice(0, 1)).vertices[0].double().cpu().numpy()
    assert np.abs(first - want).max() < 1e-4  # the bind pose undone exactly
    hips = c.joint_world("mixamorig:Hips") @ C.T
    root = motion.root_translation
    assert np.abs(hips - root).max() < 0.01  # the hips joint where the motion's root is
    np.testing.assert_allclose(c.times, np.arange(c.num_frames) / 30.0, atol=1e-6)


def _edited(path, tmp_path, edit, name):
    doc = read_document(path)
    gltf = json.loads(json.dumps(doc.gltf))
    edit(gltf)
    return write_document(tmp_path / name, gltf, doc.buffers[0])


def test_a_file_without_mesh_skin_or_animation_is_refused_saying_which(character, tmp_path):
    path = character[0]
    assert has_skinned_mesh(path)
    no_mesh = _edited(path, tmp_path, lambda g: (g.pop("meshes"), g["nodes"].pop()), "a.glb")
    assert not has_skinned_mesh(no_mesh)  # a motion: read on anny
    with pytest.raises(LoosefitInputError, match="meshes.*a mesh"):
        read_character(no_mesh, 30.0)
    unskinned = _edited(path, tmp_path, lambda g: g["nodes"][-1].pop("skin"), "b.glb")
    with pytest.raises(LoosefitInputError, match="skin.*none of them skinned"):
        read_character(unskinned, 30.0)
    still = _edited(path, tmp_path, lambda g: g.pop("animations"), "c.glb")
    with pytest.raises(LoosefitInputError, match="animations.*an animation"):
        read_character(still, 30.0)
    lines = _edited(
        path, tmp_path, lambda g: g["meshes"][0]["primitives"][0].update(mode=1), "d.glb"
    )
    with pytest.raises(LoosefitInputError, match="mode.*triangles"):
        read_character(lines, 30.0)
