import numpy as np
import pytest
import torch

from loosefit.data.format import DatasetReader
from loosefit.errors import LoosefitInputError
from loosefit.inference.timeline import RolloutConfig
from loosefit.model.motion_features import root_frames, to_root_frame
from loosefit.motion.mirror import mirror_motion
from loosefit.train.clips import (
    clip_versions,
    feature_range,
    feature_statistics,
    pad_frames,
    prepare_clips,
    rollout_evaluation,
    stack_clips,
)

FLOOR = 0.9


@pytest.fixture(scope="module")
def reader(toy_dataset):
    return DatasetReader(toy_dataset)


@pytest.fixture(scope="module")
def clips(reader):
    return prepare_clips(reader, "train", None, FLOOR, RolloutConfig(), max_frames=8)


def test_each_clip_and_its_mirror_image(reader):
    versions = list(clip_versions(reader, "train", max_frames=5, mirror=True))
    assert [name for name, _, _ in versions] == ["a", "a~mirror", "b", "b~mirror"]
    (_, motion, garment), (_, mirrored, mirror_garment) = versions[:2]
    assert motion.num_frames == 5 and garment.shape[0] == 5
    np.testing.assert_array_equal(garment, reader.read("a").garment_vertices[:5])
    np.testing.assert_array_equal(mirrored.rotations, mirror_motion(motion).rotations)
    # the skirt is symmetric: its mirror image is the reflected point set
    reflected = garment * np.float32([-1.0, 1.0, 1.0])
    for t in range(5):
        d = np.linalg.norm(mirror_garment[t][:, None] - reflected[t][None], axis=-1)
        assert d.min(1).max() < 1e-3
    assert len(list(clip_versions(reader, "train"))) == 2


def test_a_clip_on_the_rollout_timeline(reader, clips):
    assert [c.name for c in clips] == ["a", "b"]
    c = clips[0]
    cfg = RolloutConfig()
    assert c.preroll > 0 and c.length == c.preroll + 8
    assert c.features.shape[0] == c.heading.shape[0] == c.origin.shape[0] == c.length
    assert c.latent is None  # prepared without a generative model
    # the target: the simulated garment in the root frames of the motion's own frames
    from loosefit.inference.rollout import timeline

    rot, root, P = timeline(c.motion, FLOOR, cfg)
    H, p = (a.float() for a in root_frames(rot.double(), root.double()))
    want = to_root_frame(torch.from_numpy(reader.read("a").garment_vertices[:8]), H[P:], p[P:])
    torch.testing.assert_close(c.target, want)
    assert P == c.preroll


def test_pad_frames_repeats_the_last_frame():
    x = torch.arange(6.0).reshape(3, 2)
    assert pad_frames(x, 5).tolist() == [[0, 1], [2, 3], [4, 5], [4, 5], [4, 5]]
    assert pad_frames(x, 2) is x and pad_frames(x, 3) is x


def test_feature_statistics_and_range_over_the_clips(reader, clips):
    F, mean, std = feature_statistics(reader, clips, "all")
    every = torch.cat([c.features for c in clips])
    assert F == every.shape[1]
    torch.testing.assert_close(mean, every.mean(0))
    torch.testing.assert_close(std, every.std(0))
    lo, hi = feature_range(clips)
    moving = torch.cat([c.features[c.preroll :] for c in clips])
    torch.testing.assert_close(lo, moving.min(0).values)
    torch.testing.assert_close(hi, moving.max(0).values)
    with pytest.raises(LoosefitInputError) as err:
        feature_statistics(reader, clips, "lower")  # features of another joint set
    assert err.value.field == "features" and str(err.value).endswith(f"found {F}")


def test_stacked_clips_are_padded_to_the_longest(reader, clips):
    short = prepare_clips(reader, "test", None, FLOOR, RolloutConfig(), max_frames=5)[0]
    batch = stack_clips([clips[0], short], extra=[torch.ones(8, 2), torch.zeros(5, 2)])
    L, T = clips[0].length, 8
    assert batch["features"].shape == (2, L, clips[0].features.shape[1])
    assert batch["heading"].shape == (2, L, 3, 3) and batch["origin"].shape == (2, L, 3)
    assert batch["target"].shape == (2, T, *short.target.shape[1:])
    assert batch["length"].tolist() == [L, short.length]
    assert batch["preroll"].tolist() == [clips[0].preroll, short.preroll]
    torch.testing.assert_close(batch["target"][1, 4:], short.target[-1:].expand(4, -1, -1))
    torch.testing.assert_close(
        batch["features"][1, short.length :], short.features[-1:].expand(L - short.length, -1)
    )
    assert batch["extra"].shape == (2, T, 2) and "latent" not in batch
    # a process's part of a batch, padded to the whole batch's longest
    part = stack_clips([short], longest=[clips[0], short])
    assert part["target"].shape[1] == T and part["features"].shape[1] == L


class _Perfect:
    """A stand-in model answering each held-out clip with its simulation, 1 cm off."""

    def __init__(self, reader):
        self.template, self.reader, self.path = reader.template, reader, reader.root / "m.pt"
        self.stages = []

    def animate(self, motion, stages=None, **_):
        from types import SimpleNamespace

        self.stages.append(stages)
        v = self.reader.read(motion.name).garment_vertices[: motion.num_frames] + np.float32(
            [0.01, 0, 0]
        )
        return SimpleNamespace(vertices=v, frames_per_second=1.0)


def test_the_rollout_evaluation_notes_and_returns_the_held_out_error(reader):
    model, record, lines = _Perfect(reader), {}, []
    out = rollout_evaluation(model, reader, "the stages", 3, record, lines.append)
    assert record["test_rollout_rmse_cm"] == pytest.approx(1.0, rel=1e-4)
    assert out == {"test/rollout_rmse_cm": record["test_rollout_rmse_cm"]}
    assert lines == [f"epoch 3: held-out rollout RMSE {record['test_rollout_rmse_cm']:.2f} cm"]
    assert model.stages == ["the stages"]
