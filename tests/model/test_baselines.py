"""The baselines' network: its skinning against a plain loop, its shapes and its errors."""

from __future__ import annotations

import pytest
import torch

from loosefit.errors import LoosefitInputError
from loosefit.model.baselines import (
    BaselineConfig,
    BaselineLossConfig,
    BaselineNetwork,
    baseline_loss,
)

V, K, F = 6, 3, 7


def _loop_skin(rest: torch.Tensor, weights: torch.Tensor, A: torch.Tensor) -> torch.Tensor:
    """x_i = sum_k w_ik (A_k[:, :3] r_i + A_k[:, 3]) for one frame, vertex by vertex."""
    out = torch.zeros(len(rest), 3)
    for i in range(len(rest)):
        for k in range(len(A)):
            out[i] += weights[i, k] * (A[k, :, :3] @ rest[i] + A[k, :, 3])
    return out


def _network(method: str, seed: int = 0) -> BaselineNetwork:
    g = torch.Generator().manual_seed(seed)
    rest = torch.randn(V, 3, generator=g)
    weights = torch.rand(V, K, generator=g)
    weights = weights / weights.sum(1, keepdim=True)
    mean = torch.randn(K, 3, 4, generator=g)
    cfg = BaselineConfig(method=method, motion_fc=8, gru=10, head_hidden=12)
    return BaselineNetwork(
        cfg, F, rest, weights, bone_mean=mean if method != "santesteban" else None
    )


def test_santesteban_skins_the_template_plus_displacements_to_the_joints():
    net = _network("santesteban")
    g = torch.Generator().manual_seed(1)
    h, _ = net.encode(torch.randn(2, 5, F, generator=g), net.initial_hidden(2))
    joints = torch.randn(2, 5, K, 3, 4, generator=g)
    out = net.decode(h, joints)["vertices"]
    assert out.shape == (2, 5, V, 3)
    # untrained: no displacement, the template skinned (checked against the loop)
    torch.testing.assert_close(out[1, 3], _loop_skin(net.rest, net.skin_weights, joints[1, 3]))
    with torch.no_grad():
        net.displacement[-1].bias.fill_(0.1)
    out = net.decode(h, joints)["vertices"]
    torch.testing.assert_close(
        out[0, 2], _loop_skin(net.rest + 0.1, net.skin_weights, joints[0, 2])
    )
    with pytest.raises(LoosefitInputError, match="joints"):
        net.decode(h, joints[:, :, :2])


def test_virtual_bones_skin_the_rest_by_predicted_bones_plus_a_residual():
    net = _network("virtual-bones")
    g = torch.Generator().manual_seed(2)
    h, hidden = net.encode(torch.randn(3, 4, F, generator=g), net.initial_hidden(3))
    assert hidden.shape == (1, 3, 10)
    out = net.decode(h)
    assert out["vertices"].shape == (3, 4, V, 3) and out["transforms"].shape == (3, 4, K, 3, 4)
    # untrained: every frame the decomposition's mean pose, no residual
    A = out["transforms"][2, 1]
    torch.testing.assert_close(A, net.bone_layer.bias.view(K, 3, 4))
    want = _loop_skin(net.rest, net.skin_weights, A)
    torch.testing.assert_close(out["coarse"][2, 1], want)
    torch.testing.assert_close(out["vertices"][2, 1], want)
    with torch.no_grad():
        net.residual[-1].bias.fill_(-0.05)
    out = net.decode(h)
    want = _loop_skin(net.rest - 0.05, net.skin_weights, out["transforms"][0, 0])
    torch.testing.assert_close(out["vertices"][0, 0], want)


def test_the_loss_has_each_methods_terms_and_is_zero_on_the_truth():
    for method, keys in (
        ("santesteban", {"geometry"}),
        ("virtual-bones", {"geometry", "coarse", "transforms"}),
    ):
        net = _network(method)
        h, _ = net.encode(torch.zeros(1, 2, F), net.initial_hidden(1))
        joints = torch.randn(1, 2, K, 3, 4) if method == "santesteban" else None
        out = net.decode(h, joints)
        bones = out.get("transforms")
        terms = baseline_loss(
            out,
            out["vertices"].detach(),
            None if bones is None else bones.detach(),
            BaselineLossConfig(),
        )
        assert set(terms) == keys | {"total"}
        assert float(terms["geometry"].detach()) == 0.0
        shifted = baseline_loss(out, out["vertices"].detach() + 0.01, None, BaselineLossConfig())
        # (1 cm)^2 on each of 3 axes
        assert float(shifted["geometry"].detach()) == pytest.approx(3.0, rel=1e-5)


def test_bad_configurations_and_inputs_are_clear_errors():
    with pytest.raises(LoosefitInputError, match="method"):
        BaselineConfig(method="smpl")
    with pytest.raises(LoosefitInputError, match="gru"):
        BaselineConfig(gru=0)
    with pytest.raises(LoosefitInputError, match="rest"):
        BaselineNetwork(BaselineConfig(), F, torch.zeros(V + 1, 3), torch.ones(V, K) / K)
    with pytest.raises(LoosefitInputError, match="bone_mean"):
        BaselineNetwork(
            BaselineConfig(method="virtual-bones"),
            F,
            torch.zeros(V, 3),
            torch.ones(V, K) / K,
            bone_mean=torch.zeros(K + 1, 3, 4),
        )
    net = _network("santesteban")
    with pytest.raises(LoosefitInputError, match="features"):
        net.encode(torch.zeros(1, 2, F + 1), net.initial_hidden(1))
