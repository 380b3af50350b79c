"""The garment's settled drape on the rest pose, for data sets that do not record it.

Every simulated clip starts from this drape (moved to where its motion starts), and so
does every learned rollout: the motion stage trains from it. The simulator records it in
every data set it makes (``rest_drape.npy``); a data set made before it did holds only
the template and the clips' frames, so this runs the settle phase again with the data
set's own cloth configuration (``manifest.json``'s ``config.cloth``). ``loosefit train
motion`` passes it to training (:func:`~loosefit.train.motion.train_motion`'s
``settle``), which itself runs no simulator.
"""

from __future__ import annotations

import torch

from loosefit.data.format import DatasetReader
from loosefit.errors import LoosefitInputError


def settled_rest_drape(reader: DatasetReader, fps: float) -> torch.Tensor:
    """(V, 3) float32 the data set's garment settled on the rest pose, in the rest pose's
    root frame, simulated on the CPU with the data set's cloth configuration.

    Args:
        reader: the data set.
        fps: the frame rate of its clips (the settle phase steps whole frames).

    Raises:
        LoosefitInputError: the manifest records no cloth configuration.
    """
    from loosefit.body.avatar import Avatar, AvatarConfig
    from loosefit.sim.cloth_config import ClothConfig
    from loosefit.sim.driver import settle

    cloth = reader.manifest.get("config", {}).get("cloth")
    if cloth is None:
        raise LoosefitInputError(
            reader.root / "manifest.json",
            "config.cloth",
            "the cloth configuration of the simulation (to settle the garment where "
            "rollouts start)",
            "none",
        )
    cloth = {**cloth, "device": "cpu"}
    avatar = Avatar(AvatarConfig(shape=dict(reader.body.get("shape", {}))), device="cpu")
    return torch.from_numpy(settle(avatar, reader.template, ClothConfig(**cloth), fps))
