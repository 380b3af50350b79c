"""The engine tier's basis and step (loosefit.model.engine)."""

import pytest
import torch

from loosefit.errors import LoosefitInputError
from loosefit.model.engine import (
    EngineConfig,
    EngineTier,
    correlate_noise,
    fit_basis,
    project,
    reconstruct,
)


def test_basis_is_the_pca():
    gen = torch.Generator().manual_seed(0)
    x = torch.randn(400, 5, 3, generator=gen) * torch.linspace(0.1, 2.0, 15).view(5, 3)
    b = fit_basis(x, 4)
    xc = (x - x.mean(0)).reshape(400, 15).double()
    values = torch.linalg.eigvalsh(xc.T @ xc / 400).flip(0)[:4]
    torch.testing.assert_close(b.scale.double() ** 2, values, rtol=1e-4, atol=1e-8)
    flat = b.basis.reshape(4, 15)
    torch.testing.assert_close(flat @ flat.T, torch.eye(4), atol=1e-5, rtol=0)
    assert float(b.explained.sum()) == pytest.approx(
        float(values.sum() / xc.pow(2).mean(0).sum()), rel=1e-4
    )


def test_full_basis_reconstructs_exactly():
    x = torch.randn(50, 4, 3, generator=torch.Generator().manual_seed(1))
    b = fit_basis(x, 12)
    y = reconstruct(project(x, b.mean, b.basis), b.mean, b.basis)
    torch.testing.assert_close(y, x, atol=1e-4, rtol=0)


def test_basis_size_is_checked():
    with pytest.raises(LoosefitInputError, match="k"):
        fit_basis(torch.zeros(3, 2, 3), 4)


def test_step_shapes_and_decode():
    x = torch.randn(60, 6, 3, generator=torch.Generator().manual_seed(2))
    b = fit_basis(x, 3)
    tier = EngineTier(7, EngineConfig(basis=3, motion_fc=8, gru=5, head=6), b)
    c, h = tier(torch.randn(2, 7), tier.initial_coefficients(2), tier.initial_hidden(2))
    assert c.shape == (2, 3) and h.shape == (2, 5)
    torch.testing.assert_close(tier.decode(c), reconstruct(c, b.mean, b.basis))
    with pytest.raises(LoosefitInputError, match="features"):
        tier(torch.randn(2, 6), c, h)


def test_features_outside_the_training_range_are_read_at_its_edge():
    x = torch.randn(60, 6, 3, generator=torch.Generator().manual_seed(3))
    low, high = -torch.ones(7), torch.ones(7)
    tier = EngineTier(
        7,
        EngineConfig(basis=3, motion_fc=8, gru=5, head=6),
        fit_basis(x, 3),
        feature_low=low,
        feature_high=high,
    )
    c0, h0 = tier.initial_coefficients(2), tier.initial_hidden(2)
    far = torch.tensor([[1e3, -1e3, 0.5, 0, 0, 0, 2], [0.1, 0, 0, -3, 0, 0, 0]])
    torch.testing.assert_close(tier(far, c0, h0), tier(far.clamp(-1, 1), c0, h0))
    assert not torch.allclose(tier(far, c0, h0)[0], tier(far * 0, c0, h0)[0])


def test_correlated_noise_is_an_ar1_process_of_unit_variance():
    white = torch.randn(20000, 8, generator=torch.Generator().manual_seed(0))
    assert correlate_noise(white, 0.0) is white
    z = correlate_noise(white, 0.9)
    assert abs(float(z.var()) - 1.0) < 0.1  # stationary: each z_t standard normal
    lag1 = float((z[1:] * z[:-1]).mean())
    assert abs(lag1 - 0.9) < 0.05
    # a plain loop of the recursion
    ref = [white[0]]
    for t in range(1, 50):
        ref.append(0.9 * ref[-1] + (1 - 0.81) ** 0.5 * white[t])
    torch.testing.assert_close(z[:50], torch.stack(ref))
    # carried on across windows: the same process as in one piece
    first = correlate_noise(white[:30], 0.9)
    second = correlate_noise(white[30:60], 0.9, previous=first[-1])
    torch.testing.assert_close(torch.cat([first, second]), z[:60])


def test_noise_correlation_is_checked():
    with pytest.raises(LoosefitInputError, match="noise_correlation"):
        EngineConfig(noise=4, noise_correlation=1.0)
