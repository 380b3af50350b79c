import pytest
import torch

from loosefit.data.dataset import FrameDataset, WindowDataset, collate_samples
from loosefit.data.format import DatasetReader
from loosefit.errors import LoosefitInputError


@pytest.fixture(scope="module")
def reader(toy_dataset):
    return DatasetReader(toy_dataset)


def _clips(reader, split):
    return [reader.read(n) for n in reader.training_clips(split)]


def test_every_frame_of_the_split_in_order(reader):
    frames = FrameDataset(reader, "train")
    want = [(s, t) for s, seq in enumerate(_clips(reader, "train")) for t in range(seq.num_frames)]
    assert len(frames) == len(want) == 32  # two clips of 16 frames
    clips = _clips(reader, "train")
    for i, (s, t) in enumerate(want):
        sample = frames[i]
        assert (sample.sequence, sample.frame) == (s, t)
        seq = clips[s]
        assert torch.equal(sample.garment, torch.from_numpy(seq.garment_vertices[t]))
        assert torch.equal(sample.rotations, torch.from_numpy(seq.motion.rotations[t]))
        assert torch.equal(
            sample.root_translation, torch.from_numpy(seq.motion.root_translation[t])
        )
    assert len(FrameDataset(reader, "test")) == 16


def test_windows_start_every_stride_frames_within_each_clip(reader):
    windows = WindowDataset(reader, "train", window=6, stride=4)
    want = [(s, t) for s in range(2) for t in range(0, 16 - 6 + 1, 4)]  # 0, 4, 8 in each
    assert [(w.sequence, w.frame) for w in windows] == want
    clips = _clips(reader, "train")
    w = windows[4]  # the second clip from frame 4
    assert w.garment.shape == (6, *clips[1].garment_vertices.shape[1:])
    assert torch.equal(w.garment, torch.from_numpy(clips[1].garment_vertices[4:10]))
    assert torch.equal(w.rotations, torch.from_numpy(clips[1].motion.rotations[4:10]))
    assert len(WindowDataset(reader, "train", window=16, stride=100)) == 2  # one per clip


def test_windows_refuse_a_bad_size_or_clips_too_short(reader):
    with pytest.raises(LoosefitInputError, match="window/stride': expected >= 1, found 0/1"):
        WindowDataset(reader, "train", window=0, stride=1)
    with pytest.raises(LoosefitInputError, match="at least one sequence of 17 frames.*16"):
        WindowDataset(reader, "train", window=17)


def test_collated_samples_stack_on_a_batch_axis(reader):
    windows = WindowDataset(reader, "train", window=3, stride=5)
    batch = collate_samples([windows[0], windows[3], windows[2]])
    assert batch.garment.shape == (3, 3, *windows[0].garment.shape[1:])
    assert torch.equal(batch.garment[1], windows[3].garment)
    assert torch.equal(batch.root_translation[2], windows[2].root_translation)
    assert batch.sequence.tolist() == [windows[i].sequence for i in (0, 3, 2)]
    assert batch.frame.tolist() == [windows[i].frame for i in (0, 3, 2)]
