import numpy as np
import pytest
import torch

from loosefit.body.avatar import ARM_BONES, Avatar, AvatarConfig, farthest_point_sampling
from loosefit.errors import LoosefitInputError
from loosefit.geometry.cap import boundary_loops
from loosefit.geometry.query import closest_points
from loosefit.types import Motion


def test_output_shapes(avatar):
    T, J = 5, avatar.num_joints
    rot = torch.eye(3).expand(T, J, 3, 3).clone()
    body = avatar.pose(rot, torch.zeros(T, 3))
    Vb = avatar.rest_vertices.shape[0]
    assert J == 31 and Vb == 13718
    assert body.vertices.shape == (T, Vb, 3)
    assert body.joint_transforms.shape == (T, J, 4, 4)
    assert body.joint_poses.shape == (T, J, 4, 4)
    assert body.faces.shape[1] == 3


def test_rest_pose_reproduces_rest_mesh(avatar):
    motion = avatar.rest_motion(2)
    body = avatar.pose_motion(motion)
    offset = torch.tensor([0.0, 0.0, avatar.floor_height])
    assert torch.allclose(body.vertices[0], avatar.rest_vertices + offset, atol=1e-5)
    # Standing on the floor: the soles touch z = 0.
    assert abs(float(body.vertices[0, :, 2].min())) < 1e-5
    # Skinning transforms at the rest pose are pure translations by the root offset.
    eye = torch.eye(3).expand(avatar.num_joints, 3, 3)
    assert torch.allclose(body.joint_transforms[0, :, :3, :3], eye, atol=1e-5)


def test_skinning_transforms_reproduce_posed_mesh(avatar):
    """Linear blend skinning with our transforms and anny's weights gives anny's vertices."""
    rng = np.random.default_rng(0)
    from loosefit.geometry.rotations import axis_angle_to_matrix

    rot = axis_angle_to_matrix(rng.normal(0, 0.3, (2, avatar.num_joints, 3))).astype(np.float32)
    body = avatar.pose(torch.from_numpy(rot), torch.tensor([[0.1, 0.2, 0.9], [0.0, 0.0, 1.0]]))
    w, idx = avatar.model.vertex_bone_weights, avatar.model.vertex_bone_indices.long()
    M = (w[None, :, :, None, None] * body.joint_transforms[:, idx]).sum(2)  # (T, Vb, 4, 4)
    v = (M[..., :3, :3] @ avatar.rest_vertices[None, :, :, None])[..., 0] + M[..., :3, 3]
    assert torch.allclose(v, body.vertices, atol=1e-4)


def test_yaw_turns_the_body_about_z(avatar):
    motion = avatar.rest_motion(1)
    rot = motion.rotations.copy()
    rot[0, 0] = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]], np.float32)  # +90 deg about Z
    body = avatar.pose(torch.from_numpy(rot), torch.from_numpy(motion.root_translation))
    nose = int(avatar.rest_vertices[:, 1].argmin())  # the most forward (-Y) point
    # Facing -Y turned 90 degrees left faces +X.
    assert body.vertices[0, nose, 0] > 0.05


def test_proxy_encloses_lower_body(avatar):
    body = avatar.pose_motion(avatar.rest_motion(1), with_proxy=True)
    full = avatar.pose_motion(avatar.rest_motion(1)).vertices[0].numpy()
    hit = closest_points(body.vertices[0].numpy(), body.faces.numpy(), full)
    region = avatar.vertices_of_bones(("Hips", "LowerBack", "Spine", "LeftUpLeg", "RightUpLeg"))
    region = region.numpy()
    outside = region[~hit.inside[region]]
    # Only a crease may poke through, by far less than the proxy's 5 mm margin.
    assert len(outside) <= 0.002 * len(region)
    assert hit.distance[outside].max(initial=0.0) < 0.002
    assert body.vertices.shape[1] < 2000


def test_seed_points_are_spread_and_rigid(avatar):
    seeds = avatar.seed_points(64)
    assert seeds.rest.shape == (64, 3)
    d = torch.cdist(seeds.rest, seeds.rest) + torch.eye(64) * 10
    assert float(d.min()) > 0.02  # regularly spread, no clumps
    rng = np.random.default_rng(1)
    from loosefit.geometry.rotations import axis_angle_to_matrix

    rot = axis_angle_to_matrix(rng.normal(0, 0.2, (3, avatar.num_joints, 3))).astype(np.float32)
    body = avatar.pose(torch.from_numpy(rot), torch.zeros(3, 3))
    R, t = avatar.seed_frames(seeds, body)
    posed = (R @ seeds.rest[None, :, :, None])[..., 0] + t
    assert torch.allclose(posed, body.vertices[:, seeds.vertex_indices], atol=1e-4)
    eye = torch.eye(3).expand_as(R)
    assert torch.allclose(R @ R.transpose(-1, -2), eye, atol=1e-4)


def test_farthest_point_sampling_matches_naive():
    pts = torch.from_numpy(np.random.default_rng(2).normal(size=(200, 3)))
    got = farthest_point_sampling(pts, 10, start=3).tolist()
    chosen = [3]
    for _ in range(9):
        dist = [min(float((pts[i] - pts[c]).norm()) for c in chosen) for i in range(200)]
        chosen.append(int(np.argmax(dist)))
    assert got == chosen


def test_motion_with_wrong_joints_is_rejected(avatar):
    bad = Motion(("a", "b"), np.tile(np.eye(3), (2, 2, 1, 1)), np.zeros((2, 3)), 30.0, "bad")
    with pytest.raises(LoosefitInputError, match="joint_names.*missing"):
        avatar.pose_motion(bad)


def test_pose_rejects_wrong_shapes(avatar):
    with pytest.raises(LoosefitInputError, match="rotations"):
        avatar.pose(torch.eye(3).expand(2, 5, 3, 3), torch.zeros(2, 3))
    with pytest.raises(LoosefitInputError, match="root_translation"):
        avatar.pose(torch.eye(3).expand(2, 31, 3, 3), torch.zeros(3, 3))


def test_unknown_shape_parameter_is_rejected():
    with pytest.raises(LoosefitInputError, match="tallness"):
        Avatar(AvatarConfig(shape={"tallness": 0.5}))
    with pytest.raises(LoosefitInputError, match="height"):
        Avatar(AvatarConfig(shape={"height": 1.5}))


def test_armless_collider_is_closed_and_keeps_the_torso(avatar):
    full = avatar.collider_faces(arms=True)
    assert full is avatar.faces
    faces = avatar.collider_faces(arms=False).numpy()
    assert boundary_loops(faces) == []  # closed again
    arm = avatar.vertices_of_bones(ARM_BONES).numpy()
    used = np.unique(faces)
    # Only the ring of arm vertices along the shoulder cut is still used.
    assert np.isin(arm, used).mean() < 0.05
    # Inside/outside still works on it: points inside the torso and the hands' rest places.
    v = avatar.rest_vertices.numpy()
    hand = avatar.vertices_of_bones(("LeftHand", "RightHand")).numpy()
    queries = np.array([[0.0, 0.0, 0.25], [0.0, 0.0, -0.05]], np.float32)  # chest, pelvis
    queries = np.concatenate([queries, v[hand].mean(0, keepdims=True)])
    hit = closest_points(v, faces, queries)
    assert hit.inside.tolist() == [True, True, False]


def test_the_cut_arms_are_a_closed_collider_of_their_own(avatar):
    v = avatar.rest_vertices.numpy()
    hand = avatar.vertices_of_bones(("LeftHand",)).numpy()
    for arms in (False, "upper"):
        faces = avatar.cut_limb_faces(arms).numpy()
        assert boundary_loops(faces) == []  # closed at the cut
        # outward: a positive volume, far smaller than the body's
        tri = v[faces]
        volume = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6
        assert 0.001 < volume < 0.01
        queries = np.stack([v[hand].mean(0), [0.0, 0.0, 0.25]]).astype(np.float32)
        hit = closest_points(v, faces, queries)  # the left hand's middle, the chest
        assert hit.inside.tolist() == [True, False]
    with pytest.raises(LoosefitInputError, match="arms"):
        avatar.cut_limb_faces(True)
