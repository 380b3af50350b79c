"""The detail stage (paper 3.4): the detail generator's residual on the decoded garment."""

from __future__ import annotations

from collections.abc import Callable

import torch

from loosefit.inference.stages import StageFrames
from loosefit.model.motion_features import from_root_frame, to_root_frame

# garments (n, V, 3) in their root frames and codes (n, Z) -> the residual I_de (n, V, 3):
# a DetailGenerator, or the ONNX runtime's detail runner
DetailNetwork = Callable[[torch.Tensor, torch.Tensor], torch.Tensor]


class DetailStage:
    """Each frame's garment plus the detail generator's residual, taken in its root frame.

    Args:
        network: ``(V_t, Z_t) -> I_de``, garments (n, V, 3) in their root frames.
        device: where the network runs.
    """

    name = "detail"

    def __init__(self, network: DetailNetwork, device: torch.device | str = "cpu") -> None:
        self.network, self.device = network, device

    def __call__(self, frames: StageFrames) -> torch.Tensor:
        """(n, V, 3) world garments with their detail."""
        h, q = frames.headings.to(self.device), frames.origins.to(self.device)
        local = to_root_frame(frames.vertices.to(self.device), h, q)
        local = local + self.network(local, frames.codes.to(self.device))
        return from_root_frame(local, h, q).cpu()
