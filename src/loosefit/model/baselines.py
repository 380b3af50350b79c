"""The paper's two baselines (4.3, Table 3) as configurations of one network.

Both read the same motion features as the dynamic motion encoder
(:mod:`loosefit.model.motion_features`) through the same trunk (a fully
connected layer and a GRU), never the previous garment, and pose the garment by
linear blend skinning (:func:`~loosefit.geometry.skinning.linear_blend_skinning`)
in the body's root frame, as the learned models do everywhere here:

* ``santesteban`` (Santesteban et al. 2019, "Learning-based animation of
  clothing for virtual try-on", the paper's [28]): the garment is skinned to
  the avatar's own skeleton, with weights taken from the body
  (:mod:`loosefit.geometry.skin_transfer`); the GRU predicts per-vertex
  displacements of the garment in the unposed space, ``x = LBS(T + D(h_t),
  W, G_t)`` with ``G_t`` the joints' transforms of frame t. Their post-process
  pushes vertices out of the body (:class:`~loosefit.inference.stages.push_out.PushOutHandler`).
* ``virtual-bones`` (Pan et al. 2022, "Predicting loose-fitting garment
  deformations using bone-driven motion networks", the paper's [21]): a
  skinning decomposition of the training frames (SSDR, Dem Bones,
  :mod:`loosefit.model.ssdr`) gives ``B`` virtual bones with fixed weights;
  the GRU predicts each bone's transform ``A_t`` (the low-frequency garment
  ``LBS(R, W, A_t)``) and a residual network a per-vertex offset in the rest
  space for detail, ``x = LBS(R + D(h_t, A_t), W, A_t)``.

The per-vertex output layers start at zero, so before training a Santesteban
model is the template skinned to the body and a virtual-bones model is the
decomposition's mean pose.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from loosefit.errors import LoosefitInputError
from loosefit.geometry.skinning import linear_blend_skinning
from loosefit.model.motion_features import joint_set

METHODS = ("santesteban", "virtual-bones")


@dataclass
class BaselineConfig:
    """One baseline: which, and its sizes (the trunk as the dynamic motion encoder's)."""

    method: str = "santesteban"  # one of METHODS
    motion_fc: int = 256  # the fully connected layer on the motion features
    gru: int = 500  # the GRU (as the paper's motion encoder)
    head_hidden: int = 512  # hidden width of the per-vertex output MLP
    bones: int = 32  # virtual-bones: bones asked of the skinning decomposition
    joints: str = "all"  # the joints whose rotations are features (motion_features.JOINT_SETS)

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise LoosefitInputError(
                "BaselineConfig", "method", f"one of {METHODS}", repr(self.method)
            )
        joint_set(self.joints)
        for name in ("motion_fc", "gru", "head_hidden", "bones"):
            v = getattr(self, name)
            if not (isinstance(v, int) and v > 0):
                raise LoosefitInputError("BaselineConfig", name, "a positive integer", v)


def _mlp(sizes: tuple[int, ...]) -> nn.Sequential:
    layers: list[nn.Module] = []
    for a, b in zip(sizes[:-1], sizes[1:], strict=True):
        layers += [nn.Linear(a, b), nn.LeakyReLU(0.2)]
    last = layers[-2]
    nn.init.zeros_(last.weight)
    nn.init.zeros_(last.bias)
    return nn.Sequential(*layers[:-1])


class BaselineNetwork(nn.Module):
    """Motion features -> GRU -> (displacements | bone transforms + residual) -> skinning.

    Args:
        config: the method and sizes.
        num_features: F, the length of a frame's motion features.
        rest: (V, 3) the rest shape that is skinned (the garment template, or the
            decomposition's rest shape).
        weights: (V, K) dense skinning weights: on the avatar's J joints
            (Santesteban) or on the B virtual bones.
        feature_mean: (F,) and ``feature_std`` (F,): the training set's statistics.
        bone_mean: (B, 3, 4) virtual-bones: the transforms its bone layer starts at.
    """

    def __init__(
        self,
        config: BaselineConfig,
        num_features: int,
        rest: torch.Tensor,
        weights: torch.Tensor,
        feature_mean: torch.Tensor | None = None,
        feature_std: torch.Tensor | None = None,
        *,
        bone_mean: torch.Tensor | None = None,
    ) -> None:
        super().__init__()
        self.config = cfg = config
        V, K = weights.shape
        if rest.shape != (V, 3):
            raise LoosefitInputError("BaselineNetwork", "rest", f"({V}, 3)", tuple(rest.shape))
        self.num_vertices, self.num_features, self.influences = V, num_features, K
        mean = torch.zeros(num_features) if feature_mean is None else feature_mean.float()
        std = torch.ones(num_features) if feature_std is None else feature_std.float()
        self.register_buffer("feature_mean", mean.clone())
        self.register_buffer("feature_std", std.clamp_min(1e-4).clone())
        self.register_buffer("rest", torch.as_tensor(rest).float().clone())
        self.register_buffer("skin_weights", torch.as_tensor(weights).float().clone())
        self.motion_fc = nn.Linear(num_features, cfg.motion_fc)
        self.gru = nn.GRU(cfg.motion_fc, cfg.gru, batch_first=True)
        if cfg.method == "santesteban":
            self.displacement = _mlp((cfg.gru, cfg.head_hidden, 3 * V))
        else:
            self.bone_layer = nn.Linear(cfg.gru, 12 * K)
            nn.init.zeros_(self.bone_layer.weight)
            with torch.no_grad():
                start = torch.zeros(K, 3, 4) if bone_mean is None else torch.as_tensor(bone_mean)
                if start.shape != (K, 3, 4):
                    raise LoosefitInputError(
                        "BaselineNetwork", "bone_mean", f"({K}, 3, 4)", tuple(start.shape)
                    )
                self.bone_layer.bias.copy_(start.float().reshape(-1))
            self.residual = _mlp((cfg.gru + 12 * K, cfg.head_hidden, 3 * V))

    @property
    def method(self) -> str:
        return self.config.method

    def initial_hidden(self, batch: int, device=None) -> torch.Tensor:
        """(1, B, gru) zeros: the GRU's state before a timeline's first frame."""
        return torch.zeros(1, batch, self.config.gru, device=device)

    def encode(
        self, features: torch.Tensor, hidden: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """The trunk over a stretch of frames.

        Args:
            features: (B, T, F) motion features.
            hidden: (1, B, gru) the GRU's state before the first of them.

        Returns:
            h (B, T, gru), the GRU's output per frame, and the state after the last (1, B, gru).
        """
        if features.ndim != 3 or features.shape[-1] != self.num_features:
            raise LoosefitInputError(
                "BaselineNetwork", "features", f"(B, T, {self.num_features})", tuple(features.shape)
            )
        x = (features - self.feature_mean) / self.feature_std
        return self.gru(nn.functional.leaky_relu(self.motion_fc(x), 0.2), hidden)

    def decode(self, h: torch.Tensor, joints: torch.Tensor | None = None) -> dict:
        """Garments from the trunk's outputs.

        Args:
            h: (..., gru) the GRU's output of some frames.
            joints: (..., J, 3, 4) Santesteban: the avatar's rest -> root-frame joint
                transforms of those frames (``skinning.root_frame_transforms``).

        Returns:
            ``vertices`` (..., V, 3) in the root frame; virtual-bones also ``transforms``
            (..., B, 3, 4) and ``coarse`` (..., V, 3), the bones' skinning without the residual.
        """
        lead, V = h.shape[:-1], self.num_vertices
        if self.method == "santesteban":
            if joints is None or joints.shape != (*lead, self.influences, 3, 4):
                found = None if joints is None else tuple(joints.shape)
                raise LoosefitInputError(
                    "BaselineNetwork.decode", "joints", f"{(*lead, self.influences, 3, 4)}", found
                )
            unposed = self.rest + self.displacement(h).view(*lead, V, 3)
            return {"vertices": linear_blend_skinning(unposed, self.skin_weights, joints)}
        bones = self.bone_layer(h)  # (..., 12 B)
        transforms = bones.view(*lead, self.influences, 3, 4)
        offsets = self.residual(torch.cat([h, bones], -1)).view(*lead, V, 3)
        return {
            "vertices": linear_blend_skinning(self.rest + offsets, self.skin_weights, transforms),
            "coarse": linear_blend_skinning(self.rest, self.skin_weights, transforms),
            "transforms": transforms,
        }


def body_joint_weights(avatar) -> np.ndarray:
    """(Vb, J) dense skinning weights of the avatar's body vertices on its joints."""
    from loosefit.geometry.skinning import dense_weights

    m = avatar.model
    w = dense_weights(
        m.vertex_bone_weights.double().cpu(), m.vertex_bone_indices.cpu(), avatar.num_joints
    )
    return w.numpy()


@dataclass
class BaselineLossConfig:
    """Weights of the baselines' training terms and the length unit they are taken in."""

    coarse: float = 1.0  # virtual-bones: the bones' skinning alone against the simulation
    # virtual-bones: bone transforms against the decomposition's (a tenth of the geometry term
    # at the start of training on salsa: a guide for the bones, not what is fitted)
    transforms: float = 0.01
    length_scale: float = 100.0  # metres to centimetres, as the generative and motion losses


def baseline_loss(
    out: dict, target: torch.Tensor, bone_target: torch.Tensor | None, weights: BaselineLossConfig
) -> dict[str, torch.Tensor]:
    """The terms of one batch of frames.

    ``geometry``: mean squared vertex distance to the simulation (Santesteban et al.
    regress displacements in the unposed space; here the error is taken after
    skinning, on what is evaluated). Virtual bones add ``coarse`` (the bones alone)
    and ``transforms`` (squared error of the 12 entries of each bone's transform
    against the skinning decomposition's transform of the frame, in the length
    unit), as Pan et al. train the bone network on the decomposition.

    Args:
        out: :meth:`BaselineNetwork.decode` of N frames.
        target: (N, V, 3) the simulated garments, root frame.
        bone_target: (N, B, 3, 4) virtual-bones: the decomposition's transforms (else None).
        weights: the weights and the unit.

    Returns:
        The weighted terms and their sum under ``"total"``.
    """
    from loosefit.model.generative import squared_error

    s = weights.length_scale
    terms = {"geometry": squared_error(s * out["vertices"], s * target)}
    if "coarse" in out:
        terms["coarse"] = weights.coarse * squared_error(s * out["coarse"], s * target)
    if "transforms" in out and bone_target is not None:
        diff = s * (out["transforms"] - bone_target)
        terms["transforms"] = weights.transforms * diff.pow(2).sum((-1, -2)).mean()
    terms["total"] = sum(terms.values())
    return terms
