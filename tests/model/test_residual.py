"""The residual process: its fit, its draws, its record."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from loosefit.errors import LoosefitInputError
from loosefit.model.residual import (
    ResidualConfig,
    ResidualProcess,
    fit_residual_process,
    residual_draws,
    residual_offsets,
)


def _residuals(N: int = 400, V: int = 30, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    """Residuals along two known directions (2, V, 3) with std 0.03 and 0.01 m."""
    g = torch.Generator().manual_seed(seed)
    dirs = torch.linalg.qr(torch.randn(3 * V, 2, generator=g, dtype=torch.float64)).Q.T
    c = torch.randn(N, 2, generator=g, dtype=torch.float64) * torch.tensor([0.03, 0.01])
    return (c @ dirs).view(N, V, 3).float(), dirs.view(2, V, 3).float()


def test_the_fit_finds_the_residuals_directions_and_their_spread():
    r, dirs = _residuals()
    p = fit_residual_process(r, ResidualConfig(directions=2))
    assert p.basis.shape == (2, 30, 3) and p.num_vertices == 30
    for k in range(2):  # the same directions, up to sign, in order of spread
        cos = float((p.basis[k].flatten() @ dirs[k].flatten()).abs())
        assert cos > 0.99
    assert p.std[0] == pytest.approx(0.03, rel=0.15) and p.std[1] == pytest.approx(0.01, rel=0.15)


def test_draws_are_a_seed_s_own_and_of_unit_variance():
    p = ResidualProcess(torch.eye(6).view(6, 2, 3), torch.ones(6), ResidualConfig(6, 0.9, 1.0))
    a, b = residual_draws(p, 4000, 3), residual_draws(p, 4000, 3)
    assert torch.equal(a, b)
    assert not torch.equal(a, residual_draws(p, 4000, 4))
    assert a.var(0).mean() == pytest.approx(1.0, abs=0.15)
    lag = (a[1:] * a[:-1]).mean() / (a * a).mean()  # the AR(1) memory
    assert float(lag) == pytest.approx(0.9, abs=0.05)


def test_offsets_are_the_scaled_directions():
    basis = torch.zeros(2, 4, 3)
    basis[0, 0, 0] = basis[1, 3, 2] = 1.0
    p = ResidualProcess(basis, torch.tensor([0.02, 0.05]), ResidualConfig(2, 0.5, 2.0))
    off = residual_offsets(p, 10, 7)
    c = residual_draws(p, 10, 7)
    assert off.shape == (10, 4, 3)
    torch.testing.assert_close(off[:, 0, 0], 2.0 * 0.02 * c[:, 0])
    torch.testing.assert_close(off[:, 3, 2], 2.0 * 0.05 * c[:, 1])
    assert off[:, 1:3].abs().max() == 0
    assert residual_offsets(p.with_scale(0.0), 10, 7).abs().max() == 0


def test_the_record_round_trips_and_a_bad_one_is_named():
    r, _ = _residuals()
    p = fit_residual_process(r, ResidualConfig(directions=3, correlation=0.8, scale=0.5))
    q = ResidualProcess.from_dict(p.to_dict(), "residual.pt")
    assert q.config == p.config and torch.equal(q.basis, p.basis) and torch.equal(q.std, p.std)
    bad = p.to_dict()
    bad["std"] = torch.ones(2)
    with pytest.raises(LoosefitInputError, match="residual.pt.*std"):
        ResidualProcess.from_dict(bad, "residual.pt")
    bad = p.to_dict()
    bad["basis"] = bad["basis"].clone()
    bad["basis"][0, 0, 0] = float("nan")
    with pytest.raises(LoosefitInputError, match="basis"):
        ResidualProcess.from_dict(bad, "residual.pt")


@pytest.mark.parametrize(
    ("field", "value"),
    [("directions", 0), ("directions", 2.5), ("correlation", 1.0), ("correlation", -0.1),
     ("scale", -1.0)],
)  # fmt: skip
def test_a_bad_config_is_refused_naming_the_field(field, value):
    with pytest.raises(LoosefitInputError, match=field):
        ResidualConfig(**{field: value})


def test_bad_residuals_and_seeds_are_refused():
    with pytest.raises(LoosefitInputError, match="shape"):
        fit_residual_process(torch.zeros(10, 4), ResidualConfig(directions=2))
    r, _ = _residuals(N=20)
    r[3, 1, 1] = float("inf")
    with pytest.raises(LoosefitInputError, match="finite"):
        fit_residual_process(r, ResidualConfig(directions=2))
    p = ResidualProcess(torch.eye(6).view(6, 2, 3), torch.ones(6), ResidualConfig(6))
    with pytest.raises(LoosefitInputError, match="seed"):
        residual_draws(p, 5, -1)


def _spin(T: int, rate: float, fps: float = 30.0, J: int = 3) -> torch.Tensor:
    """(T, J, 3, 3) every joint turning about Z at ``rate`` rad/s."""
    angle = torch.arange(T, dtype=torch.float64) * rate / fps
    c, s = torch.cos(angle), torch.sin(angle)
    R = torch.zeros(T, 3, 3, dtype=torch.float64)
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1.0
    return R[:, None].expand(T, J, 3, 3)


def test_the_motion_s_intensity_is_its_joints_mean_angular_speed():
    from loosefit.model.residual import motion_intensity

    np.testing.assert_allclose(motion_intensity(_spin(40, 2.0).numpy(), 30.0), 2.0, rtol=1e-6)
    np.testing.assert_allclose(motion_intensity(_spin(40, 0.0).numpy(), 30.0), 0.0, atol=1e-9)
    assert motion_intensity(_spin(1, 2.0).numpy(), 30.0).shape == (1,)
    with pytest.raises(LoosefitInputError, match="rotations"):
        motion_intensity(np.zeros((5, 3, 3)), 30.0)


def test_the_spread_follows_the_intensity_through_the_gain():
    basis = torch.zeros(1, 2, 3)
    basis[0, 0, 0] = 1.0
    p = ResidualProcess(basis, torch.tensor([0.02]), ResidualConfig(1, 0.5, 1.0))
    g = p.with_gain((0.5, 0.25))
    w = np.array([0.0, 2.0, 100.0, -100.0])
    np.testing.assert_allclose(g.multiplier(w), [0.5, 1.0, 4.0, 0.1])  # clamped to 0.1-4
    plain, scaled = residual_offsets(p, 4, 3), residual_offsets(g, 4, 3, w)
    want = plain[:, 0, 0].numpy() * g.multiplier(w)
    np.testing.assert_allclose(scaled[:, 0, 0].numpy(), want, rtol=1e-6)
    assert ResidualProcess.from_dict(g.to_dict()).gain == (0.5, 0.25)
    bad = g.to_dict()
    bad["gain"] = [1.0, float("nan")]
    with pytest.raises(LoosefitInputError, match="gain"):
        ResidualProcess.from_dict(bad, "residual.pt")
    with pytest.raises(LoosefitInputError, match="frames"):
        residual_offsets(g, 4, 3, w[:2])
