"""What the exporters write: the axes, a rig's linear blend skinning against a plain loop,
vertex normals, and the refusals of meshes that cannot be written."""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.export.meshes import (
    Z_TO_Y_UP,
    AnimatedMesh,
    ExportConfig,
    Skin,
    check_meshes,
    in_up_axis,
    skin_to_write,
    vertex_normals_np,
)
from tests.meshes import cube, grid


def _pose(angle: float, t) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    m = np.eye(4)
    m[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    m[:3, 3] = t
    return m


def _two_bone_skin(T: int = 3) -> Skin:
    """A root and a child a metre up; the child turns about Z over the frames."""
    rest = np.array([[0.1, 0, 0.2], [0.1, 0, 0.8], [0.2, 0.1, 1.3], [0, 0.3, 1.9]])
    bind = np.stack([_pose(0, [0, 0, 0]), _pose(0, [0, 0, 1.0])])
    poses = np.stack(
        [np.stack([_pose(0, [0.1 * t, 0, 0]), _pose(0.4 * t, [0.1 * t, 0, 1.0])]) for t in range(T)]
    )
    weights = np.array([[1.0, 0], [0.7, 0.3], [0.2, 0.8], [0, 1.0]])
    indices = np.array([[0, 1], [0, 1], [1, 0], [1, 0]])  # the third vertex's weights reversed
    weights[2] = weights[2][::-1]
    return Skin(("Hips", "Spine"), [-1, 0], rest, bind, weights, indices, poses)


def test_y_up_is_an_exact_turn_of_z_up():
    v = np.array([[1.0, 2.0, 3.0], [-0.5, 0.25, 0.125]], np.float32)
    assert in_up_axis(v, "Z") is v
    y = in_up_axis(v, "Y")
    np.testing.assert_array_equal(y, [[1, 3, -2], [-0.5, 0.125, -0.25]])  # no rounding
    np.testing.assert_allclose(y, v @ Z_TO_Y_UP.T)
    assert ExportConfig(up_axis="y").up_axis == "Y"
    with pytest.raises(LoosefitInputError, match=r"ExportConfig: field 'up_axis'.*found X"):
        ExportConfig(up_axis="X")


def test_linear_blend_skinning_is_the_weighted_sum_of_the_joints_transforms():
    skin = _two_bone_skin()
    got = skin.skinned()
    assert got.shape == (3, 4, 3) and skin.num_frames == 3
    for t in range(3):  # a plain loop over vertices and their weights
        S = skin.joint_poses[t] @ np.linalg.inv(skin.bind_poses)
        for i, r in enumerate(skin.rest_vertices):
            want = sum(
                w * (S[j] @ np.append(r, 1.0))[:3]
                for w, j in zip(skin.weights[i], skin.indices[i], strict=True)
            )
            np.testing.assert_allclose(got[t, i], want, atol=1e-12)
    np.testing.assert_allclose(skin.skinned(1, 2), got[1:2])
    assert skin.error(got) < 1e-12
    moved = got.copy()
    moved[2, 3, 0] += 0.004
    assert skin.error(moved, chunk=1) == pytest.approx(0.004)
    # the local poses: the child's in the root's frame
    local = skin.local_poses()
    np.testing.assert_allclose(local[2, 1], _pose(0.8, [0, 0, 1.0]), atol=1e-12)
    np.testing.assert_allclose(skin.local_bind_poses()[1], _pose(0, [0, 0, 1.0]))
    # an axis change turns the skinned mesh with it
    turned = skin.transformed(Z_TO_Y_UP).skinned()
    np.testing.assert_allclose(turned, got @ Z_TO_Y_UP.T, atol=1e-12)


def test_a_rig_is_written_only_when_it_reproduces_the_mesh():
    skin = _two_bone_skin()
    body = AnimatedMesh("body", [[0, 1, 2], [1, 3, 2]], skin.skinned(), skin=skin)
    assert skin_to_write(body, ExportConfig(), "x.usd") is skin
    assert skin_to_write(body, ExportConfig(skinned_body=False), "x.usd") is None
    off = AnimatedMesh("body", body.faces, body.vertices + [0, 0, 0.01], skin=skin)
    with pytest.warns(UserWarning, match="reproduces it to 10.000 mm"):
        assert skin_to_write(off, ExportConfig(), "x.usd") is None
    with pytest.warns(UserWarning, match="the body has no rig"):
        assert (
            skin_to_write(AnimatedMesh("body", body.faces, body.vertices), ExportConfig(), "x")
            is None
        )


def test_vertex_normals_are_area_weighted_and_unit():
    v, f = cube(2.0)
    n = vertex_normals_np(v, f)
    assert n.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, rtol=1e-6)
    # a plain loop: each vertex sums the cross products (twice the areas) of its faces
    for i in range(len(v)):
        s = sum(np.cross(v[b] - v[a], v[c] - v[a]) for a, b, c in f if i in (a, b, c))
        np.testing.assert_allclose(n[i], s / np.linalg.norm(s), atol=1e-6)
    assert (np.sum(n * v, axis=1) > 0).all()  # outwards
    gv, gf = grid(3, 0, 1)
    a, b, c = gv[gf[0]]
    up = np.sign(np.cross(b - a, c - a)[2])
    np.testing.assert_allclose(vertex_normals_np(gv, gf), np.broadcast_to([0, 0, up], (9, 3)))


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        (dict(name="1body"), "name"),
        (dict(name="my-dress"), "name"),
        (dict(vertices=np.zeros((0, 3, 3))), "vertices"),
        (dict(vertices=np.full((2, 3, 3), np.nan)), "vertices"),
        (dict(faces=[[0, 1, 3]]), "faces"),
        (dict(uvs=np.zeros((3, 2))), "uvs, face_uvs"),
        (dict(uvs=np.zeros((3, 2)), face_uvs=[[0, 1, 5]]), "face_uvs"),
    ],
)
def test_meshes_that_cannot_be_written_are_refused(kwargs, field):
    mesh = dict(name="garment", faces=[[0, 1, 2]], vertices=np.zeros((2, 3, 3)))
    with pytest.raises(LoosefitInputError, match=rf"field '{field}'"):
        AnimatedMesh(**{**mesh, **kwargs})


def test_meshes_exported_together_share_their_frames_and_names():
    a = AnimatedMesh("garment", [[0, 1, 2]], np.zeros((4, 3, 3)))
    b = AnimatedMesh("body", [[0, 1, 2]], np.zeros((4, 3, 3)))
    assert check_meshes([a, b], 30.0, "out.usd") == 4
    short = AnimatedMesh("body", [[0, 1, 2]], np.zeros((3, 3, 3)))
    with pytest.raises(
        LoosefitInputError,
        match=r"out\.usd: field 'meshes': expected 4 frames each, found \[4, 3\]",
    ):
        check_meshes([a, short], 30.0, "out.usd")
    with pytest.raises(LoosefitInputError, match="distinct names"):
        check_meshes([a, a], 30.0, "out.usd")
    with pytest.raises(LoosefitInputError, match="at least one animated mesh"):
        check_meshes([], 30.0, "out.usd")
    with pytest.raises(LoosefitInputError, match=r"field 'fps'"):
        check_meshes([a], 0.0, "out.usd")
