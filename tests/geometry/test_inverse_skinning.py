import math

import numpy as np
import pytest
import torch

from loosefit.errors import LoosefitInputError
from loosefit.geometry.inverse_skinning import (
    InverseSkinningConfig,
    seed_weights,
    skin,
    unposed_targets,
    unskin,
)
from loosefit.geometry.skinning import nearest_rotation


def _rot_z(angle: float) -> torch.Tensor:
    c, s = math.cos(angle), math.sin(angle)
    return torch.tensor([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _ring_garment(rings: int = 6, per_ring: int = 24) -> torch.Tensor:
    """(V, 3) a flared skirt-like set of rings around the z axis, hips near z = 0 (metres)."""
    z = torch.linspace(0.0, -0.5, rings)[:, None]  # (rings, 1)
    a = torch.linspace(0, 2 * math.pi, per_ring + 1)[:-1][None]  # (1, per_ring)
    r = 0.2 + 0.3 * -z
    pts = torch.stack([r * a.cos(), r * a.sin(), z.expand(-1, per_ring)], -1)
    return pts.reshape(-1, 3)


def _cylinder_seeds(count: int = 40) -> torch.Tensor:
    """(m, 3) points on a hip-sized cylinder, inside the ring garment."""
    g = torch.Generator().manual_seed(0)
    a = torch.rand(count, generator=g) * 2 * math.pi
    z = -torch.rand(count, generator=g) * 0.6
    return torch.stack([0.15 * a.cos(), 0.12 * a.sin(), z], -1)


def _random_frames(B: int, m: int, dtype=torch.float64, seed: int = 0):
    g = torch.Generator().manual_seed(seed)
    R = nearest_rotation(torch.randn(B, m, 3, 3, generator=g, dtype=dtype))
    t = torch.randn(B, m, 3, generator=g, dtype=dtype)
    return R, t


def test_weights_are_a_softmax_of_distance():
    x = _ring_garment().double()
    seeds = _cylinder_seeds().double()
    w = seed_weights(x, seeds, 0.05)
    assert w.shape == (x.shape[0], seeds.shape[0])
    assert torch.allclose(w.sum(-1), torch.ones(x.shape[0], dtype=torch.float64))
    # Naive loop for one vertex.
    i = 17
    e = torch.tensor([math.exp(-float((x[i] - s).norm()) / 0.05) for s in seeds])
    assert torch.allclose(w[i], (e / e.sum()).double())
    # Batch dims broadcast.
    wb = seed_weights(torch.stack([x, x + 0.1]), seeds, 0.05)
    assert wb.shape == (2, x.shape[0], seeds.shape[0]) and torch.allclose(wb[0], w)


def test_weights_sharpen_as_temperature_falls():
    x, seeds = _ring_garment(), _cylinder_seeds()
    nearest = torch.cdist(x, seeds).argmin(-1)
    previous = None
    for temperature in (1.0, 0.2, 0.05, 0.01):
        w = seed_weights(x, seeds, temperature)
        peak = w.gather(-1, nearest[:, None])[:, 0]  # weight of the nearest seed
        if previous is not None:
            assert (peak > previous).all()
        previous = peak
    assert previous.median() > 0.5  # at 1 cm the nearest seed mostly dominates
    # The paper's exp(-d) (temperature 1) in metres: nearly uniform.
    assert seed_weights(x, seeds, 1.0).max() < 3.0 / seeds.shape[0]


def test_skin_matches_naive_loop():
    x, seeds = _ring_garment().double(), _cylinder_seeds().double()
    w = seed_weights(x, seeds, 0.05)[None].expand(2, -1, -1)
    R, t = _random_frames(2, seeds.shape[0])
    posed = skin(x[None].expand(2, -1, -1), w, R, t)
    b, i = 1, 5
    expected = sum(w[b, i, j] * (R[b, j] @ x[i] + t[b, j]) for j in range(seeds.shape[0]))
    assert torch.allclose(posed[b, i], expected)


def test_unskin_inverts_skin():
    x, seeds = _ring_garment().double(), _cylinder_seeds().double()
    w = seed_weights(x, seeds, 0.05)[None]  # (1, V, m) shared by the batch
    R, t = _random_frames(3, seeds.shape[0], seed=1)
    canonical = x[None] + 0.01 * torch.randn(3, *x.shape, dtype=torch.float64)
    posed = skin(canonical, w, R, t)
    assert torch.allclose(unskin(posed, w, R, t), canonical, atol=1e-9)
    p = torch.randn(3, *x.shape, dtype=torch.float64)
    assert torch.allclose(skin(unskin(p, w, R, t), w, R, t), p, atol=1e-9)


def test_unskin_is_differentiable():
    x, seeds = _ring_garment(2, 4).double(), _cylinder_seeds(5).double()
    R, t = _random_frames(1, 5, seed=2)
    posed = torch.randn(1, x.shape[0], 3, dtype=torch.float64, requires_grad=True)
    t = t.requires_grad_()
    tmpl = x.clone().requires_grad_()
    f = lambda p, tt, c: unposed_targets(p, c, seeds, R, tt, 0.1)  # noqa: E731
    assert torch.autograd.gradcheck(f, (posed, t, tmpl))


def test_recovers_template_from_a_rigidly_moved_garment():
    template, seeds = _ring_garment(), _cylinder_seeds()
    m = seeds.shape[0]
    R0 = torch.stack([_rot_z(2.1), nearest_rotation(torch.randn(3, 3))])  # (2, 3, 3)
    t0 = torch.tensor([[0.4, -1.3, 0.9], [-2.0, 0.5, 1.1]])  # (2, 3)
    posed = template @ R0.transpose(-1, -2) + t0[:, None]  # (2, V, 3)
    R = R0[:, None].expand(2, m, 3, 3)
    t = t0[:, None].expand(2, m, 3)
    cfg = InverseSkinningConfig()
    out = unposed_targets(posed, template, seeds, R, t, cfg.temperature)
    assert out.shape == (2, template.shape[0], 3)
    assert torch.allclose(out, template.expand(2, -1, -1), atol=1e-5)


def test_avatar_root_motion_is_undone(avatar):
    """A whole-body root move: every seed frame is that rigid move, the garment returns home."""
    seeds = avatar.seed_points(count=64)
    motion = avatar.rest_motion(2)
    heading = 2.4
    motion.rotations[1, 0] = _rot_z(heading).numpy()
    motion.root_translation[1] += np.array([0.7, -0.4, 0.05], np.float32)
    body = avatar.pose_motion(motion)
    R, t = avatar.seed_frames(seeds, body)  # (2, 64, 3, 3), (2, 64, 3)
    R0 = torch.stack([torch.eye(3), _rot_z(heading)])
    t0 = torch.from_numpy(motion.root_translation)  # the rest pose has the root at the origin
    assert torch.allclose(R, R0[:, None].expand_as(R), atol=1e-5)
    assert torch.allclose(t, t0[:, None].expand_as(t), atol=1e-5)

    # A skirt-like ring garment around the avatar's hips, in the rest pose.
    hips = seeds.rest.mean(0)
    template = _ring_garment() * torch.tensor([1.3, 1.0, 1.0]) + torch.tensor(
        [hips[0], hips[1], 0.0]
    )
    posed = template @ R0.transpose(-1, -2) + t0[:, None]  # (2, V, 3)
    out = unposed_targets(posed, template, seeds.rest, R, t)
    assert torch.allclose(out, template.expand(2, -1, -1), atol=1e-5)


def test_bad_shapes_name_the_field():
    x, seeds = _ring_garment(), _cylinder_seeds(8)
    R, t = _random_frames(2, 8, dtype=torch.float32)
    w = seed_weights(x, seeds)[None]
    with pytest.raises(LoosefitInputError, match=r"'t'.*\(2, 8, 3\).*\(2, 7, 3\)"):
        skin(x[None], w, R, t[:, :7])
    with pytest.raises(LoosefitInputError, match="'weights'"):
        unskin(x[None], w[:, :, :5], R, t)
    with pytest.raises(LoosefitInputError, match="'posed'"):
        unskin(x[None, :10], w, R, t)
    with pytest.raises(LoosefitInputError, match="'seed_rest'"):
        unposed_targets(x[None], x, seeds[:5], R, t)
    with pytest.raises(LoosefitInputError, match="'temperature'"):
        seed_weights(x, seeds, 0.0)
