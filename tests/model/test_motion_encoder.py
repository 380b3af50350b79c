"""The dynamic motion encoder (Eq. 9) against its equations written out: the features
normalised, the GRU step by its gates, E_s on the previous garment, the fc to Z_t."""

from __future__ import annotations

import pytest
import torch

from loosefit.errors import LoosefitInputError
from loosefit.garment.skirt import SkirtConfig, WaistFit, make_skirt
from loosefit.model.generative import GarmentGenerativeModel, GenerativeConfig
from loosefit.model.motion_encoder import DynamicMotionEncoder, MotionEncoderConfig

F = 11  # features a frame


@pytest.fixture(scope="module")
def generative():
    torch.manual_seed(0)
    skirt = make_skirt(
        SkirtConfig(style="aline", rings=6, segments=16),
        WaistFit(center=[0.0, 0.0, 1.0], radii=[0.15, 0.1], height=1.0),
    )
    config = GenerativeConfig(
        uv_size=32, channels=(4, 4, 4, 4), latent=8, half=4, rec_hidden=(8, 8, 8)
    )
    return GarmentGenerativeModel(skirt, config).eval()


def _gru_step(cell: torch.nn.GRUCell, x: torch.Tensor, h: torch.Tensor) -> torch.Tensor:
    """One GRU step by its gates (reset r, update z, candidate n), PyTorch's gate order."""
    wr, wz, wn = cell.weight_ih.chunk(3)
    ur, uz, un = cell.weight_hh.chunk(3)
    br, bz, bn = cell.bias_ih.chunk(3)
    cr, cz, cn = cell.bias_hh.chunk(3)
    r = torch.sigmoid(x @ wr.T + br + h @ ur.T + cr)
    z = torch.sigmoid(x @ wz.T + bz + h @ uz.T + cz)
    n = torch.tanh(x @ wn.T + bn + r * (h @ un.T + cn))
    return (1 - z) * n + z * h


def test_one_frame_is_eq_9_written_out(generative):
    torch.manual_seed(1)
    mean, std = torch.randn(F), torch.rand(F) + 0.5
    enc = DynamicMotionEncoder(generative, F, MotionEncoderConfig(motion_fc=6, gru=5), mean, std)
    features, hidden = torch.randn(3, F), torch.randn(3, 5)
    previous = torch.randn(3, generative.num_vertices, 3) * 0.1
    with torch.no_grad():
        z, h = enc(features, previous, hidden)
        x = torch.nn.functional.leaky_relu(enc.motion_fc((features - mean) / std), 0.2)
        want_h = _gru_step(enc.gru, x, hidden)
        # E_s starts as the generative encoder: its (mu, logvar) of the previous garment
        state = generative.encoder(generative.uv.encode(previous))
        want_z = enc.fc(torch.cat([want_h, state], -1))
    assert z.shape == (3, 8) and h.shape == (3, 5)
    torch.testing.assert_close(h, want_h, atol=1e-6, rtol=1e-5)
    torch.testing.assert_close(z, want_z, atol=1e-6, rtol=1e-5)
    assert state.shape == (3, 16)  # 2 x latent
    torch.testing.assert_close(enc.initial_hidden(2), torch.zeros(2, 5))


def test_without_previous_state_the_garment_is_not_read(generative):
    cfg = MotionEncoderConfig(motion_fc=6, gru=5, previous_state=False)
    enc = DynamicMotionEncoder(generative, F, cfg)
    assert enc.fc.in_features == 5 and not hasattr(enc, "state_encoder")
    features, hidden = torch.randn(2, F), torch.zeros(2, 5)
    with torch.no_grad():
        a, _ = enc(features, None, hidden)
        b, _ = enc(features, torch.randn(2, 7, 3), hidden)  # any garment, even a wrong one
        want = enc.fc(
            _gru_step(enc.gru, torch.nn.functional.leaky_relu(enc.motion_fc(features), 0.2), hidden)
        )
    torch.testing.assert_close(a, b)
    torch.testing.assert_close(a, want, atol=1e-6, rtol=1e-5)


def test_a_constant_feature_s_spread_is_kept_from_dividing_by_zero(generative):
    enc = DynamicMotionEncoder(
        generative, F, MotionEncoderConfig(motion_fc=4, gru=4), feature_std=torch.zeros(F)
    )
    assert enc.feature_std.min().item() == pytest.approx(1e-4)
    cfg = MotionEncoderConfig(motion_fc=4, gru=4, init_from_generative=False)
    fresh = DynamicMotionEncoder(generative, F, cfg)
    assert not torch.equal(fresh.state_encoder.fc.weight, generative.encoder.fc.weight)


def test_wrong_inputs_and_sizes_are_refused(generative):
    enc = DynamicMotionEncoder(generative, F, MotionEncoderConfig(motion_fc=4, gru=4))
    h = enc.initial_hidden(1)
    with pytest.raises(
        LoosefitInputError, match=r"field 'features': expected \(B, 11\), found \(1, 10\)"
    ):
        enc(torch.zeros(1, 10), None, h)
    V = generative.num_vertices
    with pytest.raises(
        LoosefitInputError, match=rf"field 'previous': expected \(B, {V}, 3\), found None"
    ):
        enc(torch.zeros(1, F), None, h)
    with pytest.raises(LoosefitInputError, match=r"MotionEncoderConfig: field 'gru'"):
        MotionEncoderConfig(gru=0)
    with pytest.raises(LoosefitInputError, match="joints"):
        MotionEncoderConfig(joints="arms")
