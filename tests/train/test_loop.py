"""The training scaffold itself (loosefit.train.loop): configurations from and to plain data,
the run folder (a rerun with another configuration refused, an old run recognised), atomic
checkpoints, resuming bit for bit, and the loop's report; on a tiny stage of its own."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import pytest
import torch

import loosefit.train.loop as loop
from loosefit.errors import LoosefitInputError
from loosefit.model.generative import GenerativeConfig
from loosefit.train.baseline import TrainBaselineConfig
from loosefit.train.detail import TrainDetailConfig
from loosefit.train.generative import TrainGenerativeConfig
from loosefit.train.motion import TrainMotionConfig

CONFIGS = [TrainGenerativeConfig, TrainMotionConfig, TrainDetailConfig, TrainBaselineConfig]


# -- configurations --------------------------------------------------------------------------


@pytest.mark.parametrize("kind", CONFIGS)
def test_every_stage_config_round_trips_through_plain_data(kind):
    for name in kind.PRESETS:
        cfg = kind.preset(name)
        data = json.loads(json.dumps(cfg.to_dict()))  # as config.json holds it
        assert kind.from_dict(data).to_dict() == cfg.to_dict()


@pytest.mark.parametrize("kind", CONFIGS)
def test_unknown_keys_are_refused_naming_the_key(kind):
    data = kind().to_dict()
    with pytest.raises(LoosefitInputError, match="learning_rate"):
        kind.from_dict({**data, "learning_rate": 1.0})
    data["model"] = {**data["model"], "widht": 3}
    with pytest.raises(LoosefitInputError, match="widht"):
        kind.from_dict(data)


def test_a_field_recorded_before_it_existed_takes_its_default():
    data = TrainMotionConfig().to_dict()
    del data["precision"], data["loss"]["flare"]
    cfg = TrainMotionConfig.from_dict(data)
    assert cfg.precision == "fp32" and cfg.loss.flare == 0.0


def test_presets_set_overrides_and_refuse_unknown_names():
    cfg = TrainGenerativeConfig.preset("cpu", decoder="vertex", epochs=7, lr=None)
    assert cfg.model.decoder == "vertex" and cfg.model.uv_size == 64  # the model's field
    assert cfg.epochs == 7 and cfg.lr == 1.0e-3  # None: the preset's
    assert TrainGenerativeConfig.preset("cpu").model.decoder == "decomposed"  # not shared
    with pytest.raises(LoosefitInputError, match="huge"):
        TrainGenerativeConfig.preset("huge")
    with pytest.raises(LoosefitInputError, match="epochz"):
        TrainBaselineConfig.preset("cpu", epochz=3)
    with pytest.raises(LoosefitInputError, match="precision"):
        TrainGenerativeConfig.preset("cpu", precision="half")  # validated after overrides


# -- the run folder --------------------------------------------------------------------------


def test_a_run_folder_refuses_another_configuration(tmp_path):
    stored = {"dataset": "d", "train": TrainGenerativeConfig().to_dict()}
    loop.open_run(tmp_path, stored)
    assert json.loads((tmp_path / "config.json").read_text()) == json.loads(json.dumps(stored))
    (tmp_path / "report.json").write_text("{}")
    loop.open_run(tmp_path, stored)  # the same run: it resumes, unfinished again
    assert not (tmp_path / "report.json").exists()
    other = {"dataset": "d", "train": TrainGenerativeConfig(epochs=3).to_dict()}
    with pytest.raises(LoosefitInputError, match="another run"):
        loop.open_run(tmp_path, other)


def test_a_run_recorded_before_a_field_existed_is_recognised(tmp_path):
    stored = {"dataset": "d", "train": TrainMotionConfig().to_dict()}
    old = json.loads(json.dumps(stored))
    del old["train"]["init"], old["train"]["loss"]["membrane"]  # a run before both fields
    (tmp_path / "config.json").write_text(json.dumps(old))
    loop.open_run(tmp_path, stored)


def test_a_checkpoint_is_written_whole_or_not_at_all(tmp_path, monkeypatch):
    path = tmp_path / "checkpoint.pt"
    loop.save_checkpoint(path, {"epoch": 1})

    def failing(data, f):
        Path(f).write_bytes(b"half a checkpoint")
        raise OSError("disk full")

    monkeypatch.setattr(torch, "save", failing)
    with pytest.raises(OSError, match="disk full"):
        loop.save_checkpoint(path, {"epoch": 2})
    assert torch.load(path, weights_only=False)["epoch"] == 1  # the last whole one
    assert [p.name for p in tmp_path.iterdir()] == ["checkpoint.pt"]  # no partial file left


# -- the loop, on a tiny stage ---------------------------------------------------------------


@dataclass
class TinyConfig(loop.TrainerConfig):
    """A least-squares fit, for the scaffold's tests."""

    epochs: int = 6
    batch_size: int = 4
    lr: float = 0.05
    checkpoint_every: int = 2
    scale: float = 1.0  # the targets' scale (a huge one makes the loss diverge)
    noise: list = field(default_factory=list)  # nothing: a nested value that is plain data
    PRESETS: ClassVar[dict[str, dict]] = {"default": {}}


class TinyTrainer(loop.Trainer):
    label = "tiny"
    tags: ClassVar[dict[str, str]] = {"lr": "train/lr"}

    def __init__(self, config: TinyConfig, run: loop.Run):
        self.config, self.run = config, run
        self.sampling = torch.Generator().manual_seed(config.seed)
        self.x = torch.randn(16, 3)
        self.y = config.scale * (self.x @ torch.tensor([1.0, -2.0, 0.5]))
        self.model = torch.nn.Linear(3, 1)
        self.optim = torch.optim.SGD(self.model.parameters(), lr=config.lr)
        self.states = {"model": self.model, "optimizer": self.optim}

    def read_checkpoint(self, path):
        return torch.load(path, weights_only=False)

    def checkpoint_fields(self):
        return {"format": "tiny", "config": self.config.to_dict()}

    def train_epoch(self, epoch, net, bar):
        order = torch.randperm(len(self.x), generator=self.sampling)
        total = 0.0
        for b in range(0, len(order), self.config.batch_size):
            i = order[b : b + self.config.batch_size]
            loss = (net(self.x[i])[:, 0] - self.y[i]).pow(2).mean() + 0.0 * torch.randn(())
            self.optim.zero_grad()
            loss.backward()
            self.optim.step()
            total += float(loss.detach())
        return {"total": total / 4}, {"lr": self.config.lr}

    def evaluate_now(self, epoch):
        return epoch == 3

    def evaluate(self, epoch, record, write):
        record["evaluated"] = True
        return {"test/error": 0.0}

    def report(self, common, writer, epoch, history):
        return {"stage": "tiny", **common, "weight": self.model.weight.tolist()}

    def format_report(self, report):
        return f"# tiny, {report['epochs']} epochs\n"


def _train(out: Path, cfg: TinyConfig, log=lambda *_: None) -> dict:
    run = loop.Run.open(out, {"train": cfg.to_dict()}, cfg.seed, log, progress=False)
    return loop.train(TinyTrainer(cfg, run), run, "toy")


def test_the_loop_trains_logs_checkpoints_and_reports(tmp_path):
    report = _train(tmp_path, TinyConfig())
    saved = torch.load(tmp_path / "checkpoint.pt", weights_only=False)
    assert saved["epoch"] == 6 and saved["format"] == "tiny" and "sampling_rng" in saved
    history = saved["history"]
    assert [h["epoch"] for h in history] == list(range(1, 7))
    assert history[-1]["total"] < history[0]["total"] and history[0]["lr"] == 0.05
    assert history[2]["evaluated"] and "evaluated" not in history[3]
    assert report["final_loss"] == history[-1] and report["dataset"] == "toy"
    assert json.loads((tmp_path / "report.json").read_text())["stage"] == "tiny"
    assert (tmp_path / "report.md").read_text() == "# tiny, 6 epochs\n"
    assert list(tmp_path.glob("events.*"))


def test_a_stopped_run_resumes_to_the_same_weights(tmp_path, monkeypatch):
    whole = _train(tmp_path / "whole", TinyConfig())
    real, saves = loop.save_checkpoint, []

    def dying(path, data):
        real(path, data)
        saves.append(data["epoch"])
        if data["epoch"] == 4:
            raise KeyboardInterrupt  # killed right after the epoch-4 checkpoint

    monkeypatch.setattr(loop, "save_checkpoint", dying)
    with pytest.raises(KeyboardInterrupt):
        _train(tmp_path / "cut", TinyConfig())
    monkeypatch.setattr(loop, "save_checkpoint", real)
    assert saves == [2, 4] and not (tmp_path / "cut" / "report.json").exists()
    lines = []
    resumed = _train(tmp_path / "cut", TinyConfig(), log=lines.append)
    assert f"resumed {tmp_path / 'cut' / 'checkpoint.pt'} at epoch 4" in lines
    assert resumed["weight"] == whole["weight"]  # bit for bit: the RNGs were restored
    assert resumed["final_loss"] == whole["final_loss"]
    with pytest.raises(LoosefitInputError, match="another run"):
        _train(tmp_path / "cut", TinyConfig(lr=0.1))


def test_a_diverging_run_names_the_epoch(tmp_path):
    with pytest.raises(RuntimeError, match="diverged at epoch"):
        _train(tmp_path, TinyConfig(scale=1e30, lr=10.0))


def test_the_shared_fields_keep_their_place_and_a_stage_its_defaults():
    names = list(TrainGenerativeConfig().to_dict())
    shared = ["epochs", "batch_size", "lr", "weight_decay", "checkpoint_every", "max_frames"]
    assert names[:8] == [*shared, "seed", "device"]
    assert TrainGenerativeConfig().epochs == 500 and TrainDetailConfig().lr == 2.0e-4
    assert isinstance(TrainGenerativeConfig.preset("full").model, GenerativeConfig)
