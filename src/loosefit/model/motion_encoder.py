"""The dynamic motion encoder (paper 3.3, Eq. 9): body motion and the previous garment to Z_t.

``Z_t = fc(E_m(M_t) || E_s(S_{t-1}))``:

* ``E_m``: a fully connected layer and a GRU (500 units in the paper) on the
  motion features of :mod:`loosefit.model.motion_features`, normalised by the
  training set's mean and standard deviation (kept in the module);
* ``E_s``: a UV-map encoder like the generative model's ``E_gen`` on the
  previous garment frame, expressed in the *current* root frame (so the map
  shows how the cloth trails the body that has just moved). By default it
  starts from ``E_gen``'s trained weights, its output being E_gen's
  (mu, logvar) of that garment;
* ``fc``: the concatenation to the generative model's latent space, whose
  frozen decoders turn ``Z_t`` into the garment ``V_t``.

``previous_state=False`` drops ``E_s``: the "w/o ps" ablation of Table 1.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from loosefit.errors import LoosefitInputError
from loosefit.model.generative import GarmentGenerativeModel, UVEncoder
from loosefit.model.motion_features import joint_set


@dataclass
class MotionEncoderConfig:
    """Sizes of the dynamic motion encoder."""

    motion_fc: int = 256  # E_m's fully connected layer
    gru: int = 500  # E_m's GRU (the paper: 500)
    previous_state: bool = True  # E_s on the previous garment (False: the "w/o ps" ablation)
    init_from_generative: bool = True  # E_s starts from the generative encoder's weights
    # the joints whose rotations E_m sees, a key of motion_features.JOINT_SETS: "all", or
    # "lower" (the spine and legs: the joints that move what the skirt touches)
    joints: str = "all"

    def __post_init__(self) -> None:
        joint_set(self.joints)  # a known set, or a clear error
        for name in ("motion_fc", "gru"):
            v = getattr(self, name)
            if not (isinstance(v, int) and v > 0):
                raise LoosefitInputError("MotionEncoderConfig", name, "a positive integer", v)


class DynamicMotionEncoder(nn.Module):
    """``{M_t, V_{t-1}} -> Z_t``, one frame at a time, with the GRU's state carried along.

    Args:
        generative: the trained generative model (its UV layout, latent size and,
            with ``init_from_generative``, its encoder's weights; it is not kept).
        num_features: F, the length of a frame's motion features.
        config: sizes and the ablation switch.
        feature_mean: (F,) and ``feature_std`` (F,): the training set's statistics.
    """

    def __init__(
        self,
        generative: GarmentGenerativeModel,
        num_features: int,
        config: MotionEncoderConfig | None = None,
        feature_mean: torch.Tensor | None = None,
        feature_std: torch.Tensor | None = None,
    ) -> None:
        super().__init__()
        self.config = cfg = config or MotionEncoderConfig()
        gcfg = generative.config
        self.num_features = num_features
        self.num_vertices = generative.num_vertices
        self.latent = gcfg.latent
        mean = torch.zeros(num_features) if feature_mean is None else feature_mean.float()
        std = torch.ones(num_features) if feature_std is None else feature_std.float()
        self.register_buffer("feature_mean", mean.clone())
        self.register_buffer("feature_std", std.clamp_min(1e-4).clone())
        self.motion_fc = nn.Linear(num_features, cfg.motion_fc)
        self.gru = nn.GRUCell(cfg.motion_fc, cfg.gru)
        state = 0
        if cfg.previous_state:
            self.uv = generative.uv  # the UV layout (buffers only, no weights)
            self.state_encoder = UVEncoder(3, gcfg.channels, gcfg.uv_size, 2 * gcfg.latent)
            if cfg.init_from_generative:
                self.state_encoder.load_state_dict(generative.encoder.state_dict())
            state = 2 * gcfg.latent
        self.fc = nn.Linear(cfg.gru + state, gcfg.latent)

    def initial_hidden(self, batch: int, device=None) -> torch.Tensor:
        """(B, gru) zeros: the GRU's state before a motion's first frame."""
        return torch.zeros(batch, self.config.gru, device=device)

    def encode_motion(self, features: torch.Tensor, hidden: torch.Tensor) -> torch.Tensor:
        """E_m for one frame: features (B, F) and hidden (B, gru) to the new hidden (B, gru)."""
        if features.ndim != 2 or features.shape[1] != self.num_features:
            raise LoosefitInputError(
                "DynamicMotionEncoder",
                "features",
                f"(B, {self.num_features})",
                f"{tuple(features.shape)}",
            )
        x = (features - self.feature_mean) / self.feature_std
        return self.gru(nn.functional.leaky_relu(self.motion_fc(x), 0.2), hidden)

    def forward(
        self, features: torch.Tensor, previous: torch.Tensor | None, hidden: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """One frame: Eq. 9.

        Args:
            features: (B, F) the frame's motion features.
            previous: (B, V, 3) the previous garment in this frame's root frame
                (ignored, and may be None, without ``previous_state``).
            hidden: (B, gru) the GRU state after the previous frame.

        Returns:
            Z_t (B, latent) and the new hidden state (B, gru).
        """
        hidden = self.encode_motion(features, hidden)
        parts = [hidden]
        if self.config.previous_state:
            if previous is None or previous.shape[1:] != (self.num_vertices, 3):
                found = None if previous is None else tuple(previous.shape)
                raise LoosefitInputError(
                    "DynamicMotionEncoder", "previous", f"(B, {self.num_vertices}, 3)", found
                )
            parts.append(self.state_encoder(self.uv.encode(previous)))
        return self.fc(torch.cat(parts, -1)), hidden
