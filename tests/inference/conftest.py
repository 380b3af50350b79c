"""What the ONNX tests share: a committed set with every stage, a tiny untrained model, the
skip mark."""

from __future__ import annotations

from importlib.util import find_spec

import numpy as np
import pytest
import torch

import loosefit
from tests.conftest import WITH_DETAIL

needs_ort = pytest.mark.skipif(
    find_spec("onnxruntime") is None or find_spec("onnx") is None,
    reason="onnx or onnxruntime is not installed (pip install 'loosefit[onnx]')",
)


@pytest.fixture(scope="module")
def model():
    """The committed salsa set, whose detail stage the graphs carry (an
    :class:`loosefit.api.Animator`; the default dance set has no detail stage)."""
    return loosefit.load(WITH_DETAIL / "motion.pt")


def tiny_model(skirt, avatar, decoder: str, previous_state: bool):
    """An untrained model of the coarse skirt with ``decoder`` (weights from a seed)."""
    from loosefit.inference.animator import AnimationModel
    from loosefit.inference.timeline import RolloutConfig
    from loosefit.model.generative import GarmentGenerativeModel, GenerativeConfig
    from loosefit.model.motion_encoder import DynamicMotionEncoder, MotionEncoderConfig
    from loosefit.model.motion_features import num_features

    torch.manual_seed(0)
    V, bones = skirt.num_vertices, 4
    ssdr = None
    if decoder == "ssdr":
        weights = torch.softmax(torch.randn(V, bones), -1).numpy()
        mean = np.tile(np.eye(3, 4, dtype=np.float32), (bones, 1, 1))
        ssdr = (skirt.vertices, weights, mean)
    basis = None
    if decoder == "basis":  # 6 random orthonormal directions about the skirt, 1-3 cm spread
        dirs = torch.linalg.qr(torch.randn(3 * V, 6)).Q.T.reshape(6, V, 3)
        basis = (torch.from_numpy(skirt.vertices), dirs, torch.linspace(0.01, 0.03, 6))
    config = GenerativeConfig(
        decoder=decoder,
        uv_size=32,
        channels=(4, 4, 4, 4),
        latent=8,
        half=4,
        rec_hidden=(8, 8, 8),
        ssdr_bones=bones,
        basis_size=6,
    )
    gen = GarmentGenerativeModel(skirt, config, ssdr, basis).eval()
    if decoder == "basis":  # offsets too, not the zero they start at
        torch.nn.init.normal_(gen.dyn.ups[-1][-1].weight, std=0.01)
    J = len(avatar.joint_names)
    enc = DynamicMotionEncoder(
        gen, num_features(J), MotionEncoderConfig(motion_fc=8, gru=8, previous_state=previous_state)
    ).eval()
    rest = torch.from_numpy(skirt.vertices).float() - torch.tensor([0, 0, avatar.floor_height])
    return AnimationModel(
        generative=gen,
        encoder=enc,
        template=skirt,
        rest_state=rest,
        joint_names=tuple(avatar.joint_names),
        floor_height=float(avatar.floor_height),
        fps=30.0,
        body={},
        rollout_config=RolloutConfig(),
        path="tiny.pt",
    )


def tiny_baseline(model, method: str, path):
    """An untrained ``method`` baseline (tiny networks, zero rest and weights) on ``model``'s
    garment, skeleton and timeline, as if loaded from ``path``."""
    from loosefit.inference.baseline import BaselineModel
    from loosefit.model.baselines import BaselineConfig, BaselineNetwork

    V = model.template.num_vertices
    net = BaselineNetwork(
        BaselineConfig(method=method, motion_fc=8, gru=8, head_hidden=8),
        model.encoder.num_features,
        torch.zeros(V, 3),
        torch.zeros(V, 4),
    )
    return BaselineModel(
        network=net,
        template=model.template,
        joint_names=model.joint_names,
        floor_height=model.floor_height,
        fps=model.fps,
        body=model.body,
        rollout_config=model.rollout_config,
        path=path,
    )
