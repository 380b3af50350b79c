"""The motion stage's residual process: one plausible realisation of the cloth.

Cloth is chaotic: the same motion simulated again from a start a tenth of a millimetre
away lands centimetres away (docs/results/ENSEMBLE.md). The motion stage, fitted to one
simulation of each clip with a squared error, predicts the centre of what the cloth may
do. The residual process models where a simulation lands around it:

    x_t = f(M_t, x_{t-1}) + s * sum_k sigma_k c_{t,k} u_k,
    c_t = rho c_{t-1} + sqrt(1 - rho^2) e_t,   e_t ~ N(0, I)

u_k (V, 3) the leading principal directions of the motion stage's residuals (the simulated
garment less the rolled-out one, in the root frame) over the training clips, sigma_k their
standard deviations, c_t a stationary AR(1) process of unit variance drawn from a seed,
and s a scale that the validation clips choose by the energy score
(``bench/quality/residual_process.py``). The offsets are added to the garment shown and
passed to the later stages, never to the motion stage's own previous state: the dynamics
stay the trained ones, and a seed gives the same garments on every run and machine (the
draws are torch's CPU generator's).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import torch

from loosefit.errors import LoosefitInputError
from loosefit.model.engine import correlate_noise, fit_basis


@dataclass(frozen=True)
class ResidualConfig:
    """The residual process's size, memory and scale."""

    directions: int = 8  # K, the principal directions of the residuals kept (the smoothest)
    correlation: float = 0.97  # rho of the AR(1) process at the data's frame rate
    scale: float = 1.0  # s, times the training residuals' standard deviations

    def __post_init__(self) -> None:
        if not (isinstance(self.directions, int) and self.directions > 0):
            raise LoosefitInputError(
                "ResidualConfig", "directions", "a positive integer", self.directions
            )
        rho = self.correlation
        if not (isinstance(rho, (int, float)) and 0.0 <= rho < 1.0):
            raise LoosefitInputError("ResidualConfig", "correlation", "a number in [0, 1)", rho)
        if not (isinstance(self.scale, (int, float)) and self.scale >= 0.0):
            raise LoosefitInputError("ResidualConfig", "scale", "a number >= 0", self.scale)


@dataclass
class ResidualProcess:
    """A fitted residual process.

    Attributes:
        basis: (K, V, 3) orthonormal directions u_k (flat vectors of 3 V numbers).
        std: (K,) sigma_k, m.
        config: its size, memory and scale.
    """

    basis: torch.Tensor
    std: torch.Tensor
    config: ResidualConfig

    @property
    def num_vertices(self) -> int:
        return int(self.basis.shape[1])

    def with_scale(self, scale: float) -> ResidualProcess:
        """The same process at another scale s."""
        c = replace(self.config, scale=scale)
        return ResidualProcess(self.basis, self.std, c)

    def to_dict(self) -> dict:
        return {
            "config": asdict(self.config),
            "basis": self.basis.float().contiguous(),
            "std": self.std.float().contiguous(),
        }

    @classmethod
    def from_dict(cls, data: dict, source: str = "residual process") -> ResidualProcess:
        """Raises LoosefitInputError naming ``source`` and the field on a malformed record."""
        config = ResidualConfig(**data["config"])
        basis = torch.as_tensor(data["basis"]).float()
        std = torch.as_tensor(data["std"]).float()
        K = config.directions
        if basis.ndim != 3 or basis.shape[0] != K or basis.shape[2] != 3:
            raise LoosefitInputError(source, "basis", f"({K}, V, 3)", tuple(basis.shape))
        if tuple(std.shape) != (K,) or not torch.isfinite(std).all() or (std < 0).any():
            raise LoosefitInputError(source, "std", f"({K},) finite, >= 0", tuple(std.shape))
        if not torch.isfinite(basis).all():
            raise LoosefitInputError(source, "basis", "finite numbers", "NaN or infinity")
        return cls(basis, std, config)


def fit_residual_process(residuals: torch.Tensor, config: ResidualConfig) -> ResidualProcess:
    """The residual process of a motion stage's residuals.

    Args:
        residuals: (N, V, 3) the simulated garment less the motion stage's, in the root
            frame, over the training frames (N >= ``config.directions``).
        config: the process's size, memory and scale.

    Returns:
        Its principal directions and their standard deviations about the residuals' mean
        (:func:`~loosefit.model.engine.fit_basis`).
    """
    if residuals.ndim != 3 or residuals.shape[-1] != 3:
        raise LoosefitInputError("residuals", "shape", "(N, V, 3)", tuple(residuals.shape))
    if not torch.isfinite(residuals).all():
        raise LoosefitInputError("residuals", "values", "finite numbers", "NaN or infinity")
    b = fit_basis(residuals, config.directions)
    return ResidualProcess(b.basis, b.scale, config)


def residual_draws(process: ResidualProcess, frames: int, seed: int) -> torch.Tensor:
    """(frames, K) the AR(1) coefficients c_t of realisation ``seed`` (unit variance)."""
    if not (isinstance(seed, int) and seed >= 0):
        raise LoosefitInputError("realisation", "seed", "an integer >= 0", seed)
    gen = torch.Generator().manual_seed(seed)
    white = torch.randn(frames, process.config.directions, generator=gen)
    return correlate_noise(white, process.config.correlation)


def residual_offsets(process: ResidualProcess, frames: int, seed: int) -> torch.Tensor:
    """(frames, V, 3) the root-frame offsets of realisation ``seed``, float32 on the CPU:
    ``s * sum_k sigma_k c_{t,k} u_k``."""
    c = residual_draws(process, frames, seed) * (process.std * process.config.scale)
    return (c @ process.basis.flatten(1)).view(frames, process.num_vertices, 3)
