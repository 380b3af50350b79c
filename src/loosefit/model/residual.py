"""The motion stage's residual process: one plausible realisation of the cloth.

Cloth is chaotic: the same motion simulated again from a start a tenth of a millimetre
away lands centimetres away (docs/results/ENSEMBLE.md). The motion stage, fitted to one
simulation of each clip with a squared error, predicts the centre of what the cloth may
do. The residual process models where a simulation lands around it:

    x_t = f(M_t, x_{t-1}) + s * m_t * sum_k sigma_k c_{t,k} u_k,
    c_t = rho c_{t-1} + sqrt(1 - rho^2) e_t,   e_t ~ N(0, I)
    m_t = clamp(a + b w_t, 0.1, 4)

u_k (V, 3) the leading principal directions of the motion stage's residuals (the simulated
garment less the rolled-out one, in the root frame) over the training clips, sigma_k their
standard deviations, c_t a stationary AR(1) process of unit variance drawn from a seed,
and s a scale that the validation clips choose by the energy score
(``bench/quality/residual_process.py``). m_t follows the motion: w_t is its intensity
(:func:`motion_intensity`, the joints' mean angular speed), and (a, b) the line through
the motion stage's error against w_t on clips it was not trained on, divided by that
error's mean (the training clips' residuals cannot give it: they are fitted, 3.5-4.5 cm
at every speed). (1, 0): the same spread at every frame. The offsets are added to the
garment shown and passed to the later stages, never to the motion stage's own previous
state: the dynamics stay the trained ones, and a seed gives the same garments on every run
and machine (the draws are torch's CPU generator's).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np
import torch

from loosefit.errors import LoosefitInputError
from loosefit.geometry.rotations import rotation_angle
from loosefit.model.engine import correlate_noise, fit_basis

GAIN_LOW, GAIN_HIGH = 0.1, 4.0  # m_t's range
INTENSITY_WINDOW = 15  # frames the motion's intensity is averaged over (half a second)


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
    gain: tuple[float, float] = (1.0, 0.0)  # (a, b): m_t = clamp(a + b w_t, 0.1, 4)

    @property
    def num_vertices(self) -> int:
        return int(self.basis.shape[1])

    def with_scale(self, scale: float) -> ResidualProcess:
        """The same process at another scale s."""
        c = replace(self.config, scale=scale)
        return ResidualProcess(self.basis, self.std, c, self.gain)

    def with_gain(self, gain: tuple[float, float]) -> ResidualProcess:
        """The same process with another gain (a, b) on the motion's intensity."""
        a, b = (float(v) for v in gain)
        if not (np.isfinite(a) and np.isfinite(b)):
            raise LoosefitInputError("ResidualProcess", "gain", "two finite numbers", gain)
        return ResidualProcess(self.basis, self.std, self.config, (a, b))

    def multiplier(self, intensity: np.ndarray) -> np.ndarray:
        """(T,) m_t of a motion's intensity w_t (T,)."""
        a, b = self.gain
        return np.clip(a + b * np.asarray(intensity, np.float64), GAIN_LOW, GAIN_HIGH)

    def to_dict(self) -> dict:
        return {
            "config": asdict(self.config),
            "basis": self.basis.float().contiguous(),
            "std": self.std.float().contiguous(),
            "gain": [float(v) for v in self.gain],
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
        gain = data.get("gain", (1.0, 0.0))
        if len(gain) != 2 or not all(np.isfinite(float(v)) for v in gain):
            raise LoosefitInputError(source, "gain", "two finite numbers (a, b)", gain)
        return cls(basis, std, config, (float(gain[0]), float(gain[1])))


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


def residual_offsets(
    process: ResidualProcess, frames: int, seed: int, intensity: np.ndarray | None = None
) -> torch.Tensor:
    """(frames, V, 3) the root-frame offsets of realisation ``seed``, float32 on the CPU:
    ``s * m_t * sum_k sigma_k c_{t,k} u_k``; ``intensity`` (frames,) the motion's w_t
    (None: m_t = 1)."""
    c = residual_draws(process, frames, seed) * (process.std * process.config.scale)
    if intensity is not None:
        if len(intensity) != frames:
            raise LoosefitInputError("intensity", "frames", frames, len(intensity))
        c = c * torch.from_numpy(process.multiplier(intensity)).float()[:, None]
    return (c @ process.basis.flatten(1)).view(frames, process.num_vertices, 3)


def motion_intensity(rotations: np.ndarray, fps: float, window: int = INTENSITY_WINDOW):
    """(T,) rad/s: a motion's intensity w_t, the mean over its joints of each local
    rotation's angular speed from the frame before, averaged over ``window`` frames about t
    (the ends held).

    Args:
        rotations: (T, J, 3, 3) local joint rotations.
        fps: frames per second.
        window: frames averaged (odd).
    """
    R = np.asarray(rotations, np.float64)
    if R.ndim != 4 or R.shape[-2:] != (3, 3) or len(R) < 1:
        raise LoosefitInputError("motion", "rotations", "(T, J, 3, 3)", tuple(R.shape))
    if len(R) == 1:
        return np.zeros(1)
    speed = rotation_angle(R[:-1], R[1:]).mean(1) * fps  # (T - 1,): R_{t-1}^T R_t's angle
    speed = np.concatenate([speed[:1], speed])
    half = window // 2
    padded = np.pad(speed, (half, half), mode="edge")
    return np.convolve(padded, np.ones(2 * half + 1) / (2 * half + 1), mode="valid")
