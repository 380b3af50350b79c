"""PyTorch datasets over a simulated dataset: single frames and windows of consecutive frames."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch.utils.data import Dataset

from loosefit.data.format import DatasetReader
from loosefit.errors import LoosefitInputError


@dataclass
class FrameSample:
    """One frame (or a window of W frames: a leading W axis on every tensor).

    Attributes:
        garment: (V, 3) garment vertices, world frame.
        rotations: (J, 3, 3) local joint rotations.
        root_translation: (3,) root joint position.
        sequence: index of the sequence in the dataset's split.
        frame: index of the (first) frame in its sequence.
    """

    garment: torch.Tensor
    rotations: torch.Tensor
    root_translation: torch.Tensor
    sequence: int
    frame: int


def collate_samples(samples: list[FrameSample]) -> FrameSample:
    """Stack samples into a batch (a leading B axis)."""
    return FrameSample(
        garment=torch.stack([s.garment for s in samples]),
        rotations=torch.stack([s.rotations for s in samples]),
        root_translation=torch.stack([s.root_translation for s in samples]),
        sequence=torch.tensor([s.sequence for s in samples]),
        frame=torch.tensor([s.frame for s in samples]),
    )


class _SplitData:
    """All sequences of a split, loaded once into memory."""

    def __init__(self, reader: DatasetReader, split: str) -> None:
        self.reader = reader
        self.names = reader.training_clips(split)
        self.sequences = [reader.read(n) for n in self.names]
        self.lengths = np.array([s.num_frames for s in self.sequences])

    def sample(self, s: int, start: int, stop: int) -> FrameSample:
        seq = self.sequences[s]
        return FrameSample(
            garment=torch.from_numpy(seq.garment_vertices[start:stop]),
            rotations=torch.from_numpy(seq.motion.rotations[start:stop]),
            root_translation=torch.from_numpy(seq.motion.root_translation[start:stop]),
            sequence=s,
            frame=start,
        )


class FrameDataset(Dataset):
    """Every frame of every sequence of a split (for the generative model).

    Args:
        reader: the dataset.
        split: "train", "test" or "all".
    """

    def __init__(self, reader: DatasetReader, split: str = "train") -> None:
        self.data = _SplitData(reader, split)
        self.index = np.concatenate(
            [np.stack([np.full(n, s), np.arange(n)], 1) for s, n in enumerate(self.data.lengths)]
        )  # (N, 2): sequence, frame

    def __len__(self) -> int:
        return len(self.index)

    def __getitem__(self, i: int) -> FrameSample:
        s, t = (int(x) for x in self.index[i])
        sample = self.data.sample(s, t, t + 1)
        return FrameSample(sample.garment[0], sample.rotations[0], sample.root_translation[0], s, t)


class WindowDataset(Dataset):
    """Windows of ``window`` consecutive frames (for the recurrent stage).

    Args:
        reader: the dataset.
        split: "train", "test" or "all".
        window: frames per window (W).
        stride: frames between the starts of consecutive windows.
    """

    def __init__(
        self, reader: DatasetReader, split: str = "train", window: int = 50, stride: int = 25
    ) -> None:
        if window < 1 or stride < 1:
            raise LoosefitInputError("WindowDataset", "window/stride", ">= 1", f"{window}/{stride}")
        self.data = _SplitData(reader, split)
        self.window = window
        starts = [
            (s, t)
            for s, n in enumerate(self.data.lengths)
            for t in range(0, int(n) - window + 1, stride)
        ]
        if not starts:
            raise LoosefitInputError(
                reader.root,
                "sequences",
                f"at least one sequence of {window} frames",
                f"longest {int(self.data.lengths.max())}",
            )
        self.starts = np.array(starts)

    def __len__(self) -> int:
        return len(self.starts)

    def __getitem__(self, i: int) -> FrameSample:
        s, t = (int(x) for x in self.starts[i])
        return self.data.sample(s, t, t + self.window)
