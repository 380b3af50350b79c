"""The engine tier: the motion stage's dynamics on a linear garment basis.

The full model decodes a latent code through convolutional UV decoders (milliseconds a
frame). The engine tier keeps the same dynamics (the motion features of
:mod:`loosefit.model.motion_features`, a recurrent state, the previous garment) and maps
them to the K coefficients of a linear basis of the garment in the root frame, a PCA of
the training corpus's simulated garments, decoded by one matrix product::

    M_t = clamp(features_t, low, high)                       (F,)
    h_t = GRU(fc([M_t, c_{t-1} / s, z_t]), h_{t-1})
    c_t = s * head([h_t, c_{t-1} / s])                       (K,)
    V_t = mean + c_t @ basis                                 (V, 3), root frame

``z_t`` (N,) is a stochastic tier's noise, drawn from a seed (none where N = 0, the
deterministic tier), white or correlated in time (:func:`correlate_noise`): trained with
the energy score against the simulation (:mod:`loosefit.train.engine`), each seed gives one
plausible realisation of the cloth, and the same seed the same one on every machine.

``s`` (K,) are the basis's standard deviations over the corpus (the coefficients enter
and leave the networks normalised). ``low`` and ``high`` (F,) are the range of each
feature over the training frames: a motion outside it (a procedural dance bends the spine
that no capture clip bends, 1,000 standard deviations out) is read as the nearest motion
the tier was trained on. The basis is orthonormal, so the squared error of the
coefficients is the squared error of the decoded vertices within the subspace
(:func:`fit_basis`). The previous coefficients are those of the previous frame's garment
in the previous frame's root frame: the features hold the root's velocity and turn rate,
which relate the two frames; no re-projection is needed.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from loosefit.errors import LoosefitInputError
from loosefit.model.motion_features import joint_set


@dataclass
class EngineConfig:
    """Sizes of the engine tier."""

    basis: int = 64  # K, coefficients of the garment basis (chosen by measurement: docs)
    motion_fc: int = 128  # the motion features' fully connected layer
    gru: int = 128  # G, the recurrent state
    head: int = 256  # the hidden layer of the head to the coefficients
    # the joints whose rotations the features hold (motion_features.JOINT_SETS)
    joints: str = "all"
    noise: int = 0  # N, the per-frame noise of a stochastic tier; 0: deterministic
    # rho of the noise's AR(1) process, z_t = rho z_t-1 + sqrt(1 - rho^2) e_t; 0: white
    noise_correlation: float = 0.0

    def __post_init__(self) -> None:
        joint_set(self.joints)
        if not (isinstance(self.noise, int) and self.noise >= 0):
            raise LoosefitInputError("EngineConfig", "noise", "an integer >= 0", self.noise)
        rho = self.noise_correlation
        if not (isinstance(rho, (int, float)) and 0.0 <= rho < 1.0):
            raise LoosefitInputError("EngineConfig", "noise_correlation", "a number in [0, 1)", rho)
        for name in ("basis", "motion_fc", "gru", "head"):
            v = getattr(self, name)
            if not (isinstance(v, int) and v > 0):
                raise LoosefitInputError("EngineConfig", name, "a positive integer", v)


def correlate_noise(white: torch.Tensor, rho: float, previous: torch.Tensor | None = None):
    """A stationary AR(1) process of unit variance driven by ``white``.

    Args:
        white: (T, ...) standard normal draws, time first.
        rho: the correlation of consecutive steps, in [0, 1); 0 returns ``white``.
        previous: (...) the process's value before the first step (a window carrying on);
            None starts it at ``white[0]``.

    Returns:
        (T, ...) ``z_t = rho z_{t-1} + sqrt(1 - rho^2) e_t``, each z_t standard normal.
    """
    if rho == 0.0:
        return white
    gain = (1.0 - rho * rho) ** 0.5
    out = torch.empty_like(white)
    z = white[0] if previous is None else rho * previous + gain * white[0]
    out[0] = z
    for t in range(1, len(white)):
        z = rho * z + gain * white[t]
        out[t] = z
    return out


@dataclass
class GarmentBasis:
    """A linear garment basis (root frame).

    Attributes:
        mean: (V, 3) the mean garment.
        basis: (K, V, 3) orthonormal directions (as flat vectors of 3 V numbers).
        scale: (K,) the standard deviation of each coefficient over the corpus.
        explained: (K,) the share of the corpus's variance each direction explains.
    """

    mean: torch.Tensor
    basis: torch.Tensor
    scale: torch.Tensor
    explained: torch.Tensor


def fit_basis(frames: torch.Tensor, k: int) -> GarmentBasis:
    """The PCA of garments: the ``k`` leading principal directions.

    Args:
        frames: (N, V, 3) garments in their root frames (N >= k).
        k: the basis size.

    Returns:
        The basis, computed in double precision.
    """
    N, V, _ = frames.shape
    if not 0 < k <= min(N, 3 * V):
        raise LoosefitInputError("fit_basis", "k", f"1..{min(N, 3 * V)}", k)
    x = frames.reshape(N, 3 * V).double()  # (N, 3V)
    mean = x.mean(0)
    xc = x - mean
    # randomized SVD (Halko et al. 2011): the leading directions to double precision in
    # seconds, where the (3V, 3V) covariance's eigendecomposition takes minutes on a core
    gen = torch.Generator().manual_seed(0)
    q = min(k + 32, min(N, 3 * V))
    y = xc.T @ (xc @ torch.randn(3 * V, q, generator=gen, dtype=xc.dtype))  # (3V, q)
    for _ in range(3):  # power iterations, orthonormalised
        y = xc.T @ (xc @ torch.linalg.qr(y).Q)
    basis_q = torch.linalg.qr(y).Q  # (3V, q)
    _, s, vh = torch.linalg.svd(xc @ basis_q, full_matrices=False)  # (N, q)
    vectors = (basis_q @ vh.T)[:, :k]  # (3V, k)
    values = s[:k] ** 2 / N
    # a fixed sign for each direction: its largest entry positive
    sign = torch.sign(vectors.gather(0, vectors.abs().argmax(0, keepdim=True)))[0]
    vectors = vectors * sign
    total = xc.pow(2).sum() / N
    return GarmentBasis(
        mean=mean.view(V, 3).float(),
        basis=vectors.T.reshape(k, V, 3).float().contiguous(),
        scale=values.clamp_min(1e-12).sqrt().float(),
        explained=(values / total).float(),
    )


def project(x: torch.Tensor, mean: torch.Tensor, basis: torch.Tensor) -> torch.Tensor:
    """Garments (..., V, 3) to their coefficients (..., K) on an orthonormal basis
    (K, V, 3) about ``mean`` (V, 3)."""
    return (x - mean).flatten(-2) @ basis.flatten(1).T


def reconstruct(c: torch.Tensor, mean: torch.Tensor, basis: torch.Tensor) -> torch.Tensor:
    """Coefficients (..., K) to garments (..., V, 3): ``mean + c @ basis``."""
    return mean + (c @ basis.flatten(1)).unflatten(-1, mean.shape)


class EngineTier(nn.Module):
    """One frame of the engine tier for B characters (the module docstring's equations).

    Args:
        num_features: F, the motion features of a frame.
        config: sizes.
        basis: the garment basis (its ``basis`` has ``config.basis`` directions).
        feature_mean: (F,) and ``feature_std`` (F,): the training set's statistics.
        rest: (K,) the settled drape's coefficients: the previous garment of a first frame.
        feature_low: (F,) and ``feature_high`` (F,): the range of each feature over the
            training frames, to which the features are clamped (None: unbounded).
    """

    def __init__(
        self,
        num_features: int,
        config: EngineConfig,
        basis: GarmentBasis,
        feature_mean: torch.Tensor | None = None,
        feature_std: torch.Tensor | None = None,
        rest: torch.Tensor | None = None,
        *,
        feature_low: torch.Tensor | None = None,
        feature_high: torch.Tensor | None = None,
    ) -> None:
        super().__init__()
        self.config = cfg = config
        K, V = basis.basis.shape[:2]
        if K != cfg.basis:
            raise LoosefitInputError("EngineTier", "basis", f"{cfg.basis} directions", K)
        self.num_features, self.num_vertices = num_features, V
        F = num_features
        self.register_buffer(
            "feature_mean", torch.zeros(F) if feature_mean is None else feature_mean.float().clone()
        )
        std = torch.ones(F) if feature_std is None else feature_std.float()
        self.register_buffer("feature_std", std.clamp_min(1e-4).clone())
        inf = torch.full((F,), float("inf"))
        low = -inf if feature_low is None else feature_low.float().clone()
        high = inf if feature_high is None else feature_high.float().clone()
        self.register_buffer("feature_low", low)  # (F,)
        self.register_buffer("feature_high", high)  # (F,)
        self.register_buffer("mean", basis.mean.float().clone())  # (V, 3)
        self.register_buffer("basis", basis.basis.float().reshape(K, 3 * V).clone())  # (K, 3V)
        self.register_buffer("scale", basis.scale.float().clamp_min(1e-6).clone())  # (K,)
        self.register_buffer("rest", torch.zeros(K) if rest is None else rest.float().clone())
        self.motion_fc = nn.Linear(F + K + cfg.noise, cfg.motion_fc)
        self.gru = nn.GRUCell(cfg.motion_fc, cfg.gru)
        self.head = nn.Sequential(
            nn.Linear(cfg.gru + K, cfg.head), nn.LeakyReLU(0.2), nn.Linear(cfg.head, K)
        )

    def initial_hidden(self, batch: int, device=None) -> torch.Tensor:
        """(B, G) zeros: the recurrent state before a motion's first frame."""
        return torch.zeros(batch, self.config.gru, device=device)

    def initial_coefficients(self, batch: int) -> torch.Tensor:
        """(B, K) the settled drape's coefficients, repeated."""
        return self.rest[None].expand(batch, -1).clone()

    def forward(
        self,
        features: torch.Tensor,
        previous: torch.Tensor,
        hidden: torch.Tensor,
        noise: torch.Tensor | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """One frame.

        Args:
            features: (B, F) the frame's motion features.
            previous: (B, K) the previous frame's coefficients.
            hidden: (B, G) the recurrent state after the previous frame.
            noise: (B, N) standard normal draws (a stochastic tier's, N = config.noise);
                None for a deterministic tier.

        Returns:
            The coefficients (B, K) and the new state (B, G).
        """
        if features.ndim != 2 or features.shape[1] != self.num_features:
            raise LoosefitInputError(
                "EngineTier", "features", f"(B, {self.num_features})", tuple(features.shape)
            )
        inside = torch.minimum(torch.maximum(features, self.feature_low), self.feature_high)
        x = (inside - self.feature_mean) / self.feature_std
        prev = previous / self.scale  # (B, K)
        inputs = [x, prev]
        if self.config.noise:
            if noise is None or tuple(noise.shape) != (len(features), self.config.noise):
                raise LoosefitInputError(
                    "EngineTier",
                    "noise",
                    f"(B, {self.config.noise}) draws (a stochastic tier)",
                    None if noise is None else tuple(noise.shape),
                )
            inputs.append(noise)
        m = nn.functional.leaky_relu(self.motion_fc(torch.cat(inputs, -1)), 0.2)
        hidden = self.gru(m, hidden)
        c = self.head(torch.cat([hidden, prev], -1)) * self.scale
        return c, hidden

    def decode(self, c: torch.Tensor) -> torch.Tensor:
        """Coefficients (B, K) to garments (B, V, 3) in the root frame: one matrix product."""
        return self.mean + (c @ self.basis).view(-1, self.num_vertices, 3)
