"""The garment's settled drape on the rest pose, for data sets that do not record it.

Every simulated clip starts from this drape (moved to where its motion starts), and so
does every learned rollout: the motion stage trains from it. A data set of today holds
the template and the clips' frames but not the drape itself (the simulator settles the
garment for every clip and writes only the frames that follow), so this fallback runs
the settle phase again with the data set's own cloth configuration
(``manifest.json``'s ``config.cloth``). It is the one place the training stages reach
the simulator through, lazily, and only where no drape is given or cached.
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
