"""Capsules: placing them on the skeleton and pushing points out (loosefit.geometry.capsule)."""

import numpy as np
import torch

from loosefit.body.capsules import avatar_capsules, joint_frames
from loosefit.geometry.capsule import DEEP, chain_frames, push_out


def naive_push_out(x, a, b, r):
    """Point by point, capsule by capsule: the moves of every capsule a point is in, summed."""
    out = x.clone()
    for i in range(x.shape[0]):
        for n in range(x.shape[1]):
            move = torch.zeros(3, dtype=x.dtype)
            for c in range(len(r)):
                ab = b[i, c] - a[i, c]
                t = torch.clamp((x[i, n] - a[i, c]) @ ab / (ab @ ab), 0, 1)
                d = x[i, n] - (a[i, c] + t * ab)
                dist = d.norm()
                if dist < r[c]:
                    move += d * (r[c] - dist) / max(dist, DEEP * r[c])
            out[i, n] += move
    return out


def _points_and_capsules(gen: torch.Generator):
    """(2, 200, 3) points around the origin, 3 capsules' ends (2, 3, 3) each and radii (3,)."""
    x = torch.rand(2, 200, 3, generator=gen, dtype=torch.float64) - 0.5
    a = torch.rand(2, 3, 3, generator=gen, dtype=torch.float64) * 0.4 - 0.2
    b = a + torch.rand(2, 3, 3, generator=gen, dtype=torch.float64) * 0.3
    r = torch.tensor([0.1, 0.15, 0.05], dtype=torch.float64)
    return x, a, b, r


def test_push_out_equals_the_naive_loop():
    gen = torch.Generator().manual_seed(0)
    x, a, b, r = _points_and_capsules(gen)
    got = push_out(x, a, b, r, origin=torch.full((2, 3), 0.1, dtype=torch.float64))
    want = naive_push_out(x, a, b, r)
    assert (want - x).abs().max() > 0.01  # some points were inside
    torch.testing.assert_close(got, want, atol=1e-9, rtol=0)


def test_a_weighted_point_makes_its_share_of_the_move():
    gen = torch.Generator().manual_seed(1)
    x, a, b, r = _points_and_capsules(gen)
    weight = torch.rand(200, 3, generator=gen, dtype=torch.float64)
    weight[:50] = 0.0
    origin = torch.full((2, 3), 0.1, dtype=torch.float64)
    got = push_out(x, a, b, r, origin, weight)
    want = x.clone()
    for c in range(3):  # the capsules' moves, each its share, summed
        one = naive_push_out(x, a[:, c : c + 1], b[:, c : c + 1], r[c : c + 1]) - x
        want += weight[:, c : c + 1] * one
    torch.testing.assert_close(got, want, atol=1e-9, rtol=0)
    torch.testing.assert_close(got[:, :50], x[:, :50], atol=1e-12, rtol=0)  # held


def test_a_pushed_point_lies_on_the_surface():
    a, b = torch.zeros(1, 1, 3), torch.tensor([[[0.0, 0.0, 1.0]]])
    x = torch.tensor([[[0.05, 0.0, 0.5], [0.3, 0.0, 0.5], [0.0, 0.06, 1.02]]])
    y = push_out(x, a, b, torch.tensor([0.1]))
    torch.testing.assert_close(y[0, 0], torch.tensor([0.1, 0.0, 0.5]))
    torch.testing.assert_close(y[0, 1], x[0, 1])  # outside: unmoved
    assert abs(float((y[0, 2] - b[0, 0]).norm()) - 0.1) < 1e-6  # the cap


def test_capsule_frames_are_the_avatars_bones(avatar):
    from loosefit.motion.motions import load_motion

    motion = load_motion("spin", avatar).slice(0, 5)
    posed = avatar.pose_motion(motion).joint_poses[..., :3, 3].double().numpy()  # (T, J, 3)
    sk = avatar.skeleton
    parents = np.asarray(sk.parents)
    heads = np.asarray(sk.heads, np.float64)
    offsets = np.where(parents[:, None] >= 0, heads - heads[np.maximum(parents, 0)], heads)
    rot, root = motion.rotations.astype(np.float64), motion.root_translation.astype(np.float64)
    G = joint_frames(rot, root, parents, offsets)
    np.testing.assert_allclose(G[..., :3, 3], posed, atol=1e-5)
    joints = [avatar.joint_names.index(n) for n in ("LeftLeg", "Spine", "Hips")]
    R, p = chain_frames(
        torch.from_numpy(rot),
        torch.from_numpy(root),
        parents.tolist(),
        torch.from_numpy(offsets),
        joints,
    )
    np.testing.assert_allclose(p.numpy(), posed[:, joints], atol=1e-5)
    np.testing.assert_allclose(R.numpy(), G[:, joints, :3, :3], atol=1e-9)


def test_capsules_fit_the_legs_and_trunk(avatar):
    caps = {c.name: c for c in avatar_capsules(avatar)}
    assert len(caps) == 9
    assert all(0.03 < c.radius < 0.2 for c in caps.values())
    left, right = caps["left_thigh_upper"], caps["right_thigh_upper"]
    assert abs(left.radius - right.radius) < 0.005  # a symmetric body, symmetric capsules
    assert caps["left_shin"].radius < left.radius
