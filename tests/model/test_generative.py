"""The generative model: shapes of each decoder, the losses, root frames, training and resume."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from loosefit.errors import LoosefitInputError
from loosefit.fitting.place import fit_skirt
from loosefit.garment.skirt import SkirtConfig
from loosefit.model.generative import (
    GarmentGenerativeModel,
    GenerativeConfig,
    GenerativeLossConfig,
    generative_loss,
    kl_divergence,
)
from loosefit.model.motion_features import from_root_frame, heading_frames, to_root_frame
from loosefit.train.generative import TrainGenerativeConfig, load_checkpoint, train_generative

SMALL = dict(uv_size=32, channels=(4, 8, 8, 8), rec_hidden=(16, 16, 16))


@pytest.mark.parametrize("decoder", ["decomposed", "vertex", "ssdr", "basis"])
def test_decoders_give_garments_of_the_template(skirt, decoder):
    V = skirt.num_vertices
    ssdr = None
    basis = _basis(skirt) if decoder == "basis" else None
    if decoder == "ssdr":
        B = 3
        w = np.full((V, B), 1.0 / B, np.float32)
        ssdr = (skirt.vertices, w, np.tile(np.eye(3, 4, dtype=np.float32), (B, 1, 1)))
    config = GenerativeConfig(decoder=decoder, basis_size=5, **SMALL)
    model = GarmentGenerativeModel(skirt, config, ssdr=ssdr, basis=basis)
    x = torch.from_numpy(skirt.vertices)[None].repeat(2, 1, 1)
    out = model(x)
    assert out.vertices.shape == (2, V, 3) and out.mu.shape == (2, 128)
    if decoder == "decomposed":
        torch.testing.assert_close(out.vertices, out.unposed + out.offsets)
    else:
        assert out.unposed is None
    if decoder == "ssdr":  # starts at the mean transforms: identity here, the rest shape
        torch.testing.assert_close(model.decode(torch.randn(2, 128))["vertices"], x)


def _basis(skirt, k: int = 5, seed: int = 0):
    """A random orthonormal basis of ``k`` directions about the skirt, 1-5 cm spread."""
    V = skirt.num_vertices
    gen = torch.Generator().manual_seed(seed)
    dirs = torch.linalg.qr(torch.randn(3 * V, k, generator=gen)).Q.T.reshape(k, V, 3)
    return torch.from_numpy(skirt.vertices), dirs, torch.linspace(0.01, 0.05, k)


def test_the_basis_decoder_starts_as_the_projection_onto_its_basis(skirt):
    """Decoder "basis" before training: the code's first K entries are the garment's
    coefficients on the basis over their scales, the rest zero, and the decoded garment is
    the garment's projection onto the basis (what lies outside it is lost, no more)."""
    mean, dirs, scale = _basis(skirt)
    model = GarmentGenerativeModel(
        skirt,
        GenerativeConfig(decoder="basis", basis_size=5, latent=8, **SMALL),
        basis=(mean, dirs, scale),
    ).eval()
    gen = torch.Generator().manual_seed(1)
    inside = torch.randn(3, 5, generator=gen) * scale
    outside = 0.01 * torch.randn(3, *mean.shape, generator=gen)
    outside -= torch.einsum("bk,kvc->bvc", torch.einsum("bvc,kvc->bk", outside, dirs), dirs)
    x = mean + torch.einsum("bk,kvc->bvc", inside, dirs) + outside
    mu, logvar = model.encode(x)
    torch.testing.assert_close(mu[:, :5], inside / scale, atol=1e-4, rtol=0)
    torch.testing.assert_close(mu[:, 5:], torch.zeros(3, 3))
    assert (logvar == -6.0).all()  # a narrow posterior at the start
    out = model(x, sample=False)
    assert out.unposed is None and out.offsets.abs().max() == 0
    torch.testing.assert_close(out.vertices, x - outside, atol=1e-5, rtol=0)


def test_bad_configurations_and_inputs(skirt):
    with pytest.raises(LoosefitInputError, match="decoder"):
        GenerativeConfig(decoder="linear")
    with pytest.raises(LoosefitInputError, match="uv_size"):
        GenerativeConfig(uv_size=40)
    with pytest.raises(LoosefitInputError, match="ssdr"):
        GarmentGenerativeModel(skirt, GenerativeConfig(decoder="ssdr", **SMALL))
    with pytest.raises(LoosefitInputError, match="basis_size"):
        GenerativeConfig(decoder="basis", basis_size=200)  # more than the latent's 128
    with pytest.raises(LoosefitInputError, match="basis"):
        GarmentGenerativeModel(skirt, GenerativeConfig(decoder="basis", **SMALL))
    mean, dirs, scale = _basis(skirt, k=4)
    with pytest.raises(LoosefitInputError, match=r"directions \(5, "):
        GarmentGenerativeModel(
            skirt,
            GenerativeConfig(decoder="basis", basis_size=5, **SMALL),
            basis=(mean, dirs, scale),
        )
    model = GarmentGenerativeModel(skirt, GenerativeConfig(**SMALL))
    with pytest.raises(LoosefitInputError, match="vertices"):
        model.encode(torch.zeros(1, 5, 3))


def test_losses():
    mu, logvar = torch.zeros(3, 8), torch.zeros(3, 8)
    assert float(kl_divergence(mu, logvar)) == 0.0
    assert float(kl_divergence(mu + 1.0, logvar)) == pytest.approx(4.0)  # 8 * 0.5 * 1
    from loosefit.model.generative import GenerativeOutput

    target = torch.zeros(2, 4, 3)
    out = GenerativeOutput(target + 0.01, mu[:2], logvar[:2], mu[:2], target, target + 0.01)
    terms = generative_loss(out, target, target, target[0], lambda x: 0 * x, GenerativeLossConfig())
    assert float(terms["geometry"]) == pytest.approx(3.0)  # (1 cm)^2 per axis, 3 axes
    assert float(terms["unposed"]) == 0.0 and float(terms["template"]) == 0.0
    assert float(terms["total"]) == pytest.approx(3.0)


def test_root_frame_takes_out_translation_and_heading():
    c, s = np.cos(1.1), np.sin(1.1)
    T = torch.eye(4).repeat(2, 1, 1)
    T[1, :3, :3] = torch.tensor([[c, -s, 0], [s, c, 0], [0, 0, 1]], dtype=torch.float32)
    T[:, :3, 3] = torch.tensor([[0.0, 0.0, 0.9], [2.0, -1.0, 0.95]])
    H, p = heading_frames(T)
    x = torch.randn(1, 5, 3)
    world = from_root_frame(x.repeat(2, 1, 1), H, p)
    # the same root-frame garment is placed by each frame's root and heading ...
    torch.testing.assert_close(world[1], x[0] @ T[1, :3, :3].T + T[1, :3, 3])
    # ... and comes back unchanged
    torch.testing.assert_close(to_root_frame(world, H, p), x.repeat(2, 1, 1))


def _config(**kw) -> TrainGenerativeConfig:
    cfg = TrainGenerativeConfig(
        model=GenerativeConfig(**SMALL),
        epochs=25,
        batch_size=8,
        lr=2e-3,
        eval_every=1000,
        checkpoint_every=1,
    )
    for k, v in kw.items():
        setattr(cfg, k, v)
    return cfg


def test_training_lowers_the_loss_and_reports(toy_dataset, skirt, tmp_path):
    report = train_generative(
        toy_dataset, tmp_path / "run", _config(), log=lambda *_: None, progress=False
    )
    history = torch.load(tmp_path / "run" / "checkpoint.pt", weights_only=False)["history"]
    assert history[-1]["total"] < 0.5 * history[0]["total"]
    assert report["test"]["frames"] == 16 and report["train"]["frames"] == 32
    assert np.isfinite(report["test"]["rmse_cm"]) and report["test"]["hausdorff_cm"] > 0
    saved = json.loads((tmp_path / "run" / "report.json").read_text())
    assert saved["train"]["rmse_cm"] == pytest.approx(report["train"]["rmse_cm"])
    model, cfg, _ = load_checkpoint(tmp_path / "run" / "checkpoint.pt", skirt)
    assert cfg.epochs == 25 and not model.training
    # another run's configuration in the same folder is refused before any training
    with pytest.raises(LoosefitInputError, match="configuration"):
        train_generative(toy_dataset, tmp_path / "run", _config(lr=1e-3), log=lambda *_: None)


def test_checkpoint_of_another_garment_is_refused(toy_dataset, tmp_path, avatar):
    train_generative(
        toy_dataset, tmp_path / "run", _config(epochs=1), log=lambda *_: None, progress=False
    )
    other = fit_skirt(avatar, SkirtConfig(style="aline", rings=5, segments=16))
    with pytest.raises(LoosefitInputError, match="garment"):
        load_checkpoint(tmp_path / "run" / "checkpoint.pt", other)
    (tmp_path / "junk.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(LoosefitInputError, match="junk.pt"):
        load_checkpoint(tmp_path / "junk.pt")


@pytest.mark.heavy
def test_a_killed_run_resumes(toy_dataset, tmp_path):
    """The run SIGKILLs itself right after its epoch-3 checkpoint is on disk (a poll from
    here raced the toy run, which can finish 12 epochs between two looks)."""
    run = tmp_path / "run"
    repo = str(Path(__file__).resolve().parents[2])
    code = (
        f"import os, signal, sys; sys.path.insert(0, {repo!r})\n"
        "from tests.model.test_generative import _config\n"
        "import loosefit.train.generative as tg\n"
        "import loosefit.train.loop as loop\n"
        "save = loop.save_checkpoint\n"
        "def killing_save(path, data):\n"
        "    save(path, data)\n"
        "    if data['epoch'] == 3:\n"
        "        os.kill(os.getpid(), signal.SIGKILL)\n"
        "loop.save_checkpoint = killing_save\n"
        f"tg.train_generative({str(toy_dataset)!r}, {str(run)!r}, _config(epochs=12),"
        " progress=False)\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        timeout=300,
    )
    assert proc.returncode == -signal.SIGKILL
    ckpt = run / "checkpoint.pt"
    done = torch.load(ckpt, weights_only=False)["epoch"]
    assert done == 3 and not (run / "report.json").exists()
    lines = []
    train_generative(toy_dataset, run, _config(epochs=12), log=lines.append, progress=False)
    assert any(f"at epoch {done}" in line for line in lines)
    history = torch.load(ckpt, weights_only=False)["history"]
    assert [h["epoch"] for h in history] == list(range(1, 13))


def test_train_and_interpolate_commands(toy_dataset, tmp_path):
    from loosefit.cli import main

    run = tmp_path / "cli-run"
    args = ["train", "generative", "--data", str(toy_dataset), "--preset", "cpu", "--epochs", "1"]
    assert main([*args, "--max-frames", "4", "--out", str(run)]) == 0
    assert (run / "report.md").is_file() and (run / "checkpoint.pt").is_file()
    out = tmp_path / "interp"
    common = ["interpolate", "--checkpoint", str(run / "checkpoint.pt"), "--data", str(toy_dataset)]
    assert (
        main(
            [*common, "--a", "a:0", "--b", "b:3", "--steps", "3", "--size", "64", "--out", str(out)]
        )
        == 0
    )
    with np.load(out / "interpolation.npz") as z:
        assert z["vertices"].shape[0] == 3 and np.isfinite(z["vertices"]).all()
    assert any(out.glob("*.mp4"))
    # a frame the clip does not have is an error naming the option
    assert main([*common, "--a", "a:99", "--b", "b:0", "--out", str(out)]) == 2
    rec = tmp_path / "rec"
    assert (
        main(
            [
                "reconstruct",
                "--checkpoint",
                str(run / "checkpoint.pt"),
                "--data",
                str(toy_dataset),
                "--clip",
                "c",
                "--max-frames",
                "3",
                "--size",
                "64",
                "--out",
                str(rec),
            ]
        )
        == 0
    )
    from loosefit.sequence import GarmentSequence

    seq = GarmentSequence.load(rec / "reconstruction.npz")  # the one sequence format
    assert seq.garment_vertices.shape == (3, 96, 3) and seq.num_frames == 3


def test_physics_terms_train_and_are_recorded(toy_dataset, skirt, tmp_path):
    loss = GenerativeLossConfig(membrane=20.0, bending=0.5, collision=0.1)
    train_generative(
        toy_dataset,
        tmp_path / "phys",
        _config(loss=loss, epochs=8),
        log=lambda *_: None,
        progress=False,
    )
    data = torch.load(tmp_path / "phys" / "checkpoint.pt", weights_only=False)
    assert data["physics_terms"] == ["membrane", "bending", "collision"]
    history = data["history"]
    assert {"membrane", "bending", "collision"} <= set(history[0])
    assert history[-1]["membrane"] < history[0]["membrane"]
    assert all(np.isfinite(h["total"]) for h in history)
    # a run without them records none
    train_generative(
        toy_dataset, tmp_path / "plain", _config(epochs=1), log=lambda *_: None, progress=False
    )
    assert (
        torch.load(tmp_path / "plain" / "checkpoint.pt", weights_only=False)["physics_terms"] == []
    )


def test_physics_loss_weights_are_checked():
    with pytest.raises(LoosefitInputError, match="membrane"):
        GenerativeLossConfig(membrane=-1.0)
    with pytest.raises(ValueError, match="ClothStructure"):
        out = type(
            "Out",
            (),
            {
                "vertices": torch.zeros(1, 3, 3),
                "mu": torch.zeros(1, 2),
                "logvar": torch.zeros(1, 2),
                "unposed": None,
            },
        )()
        generative_loss(
            out,
            torch.zeros(1, 3, 3),
            None,
            torch.zeros(3, 3),
            lambda x: 0 * x,
            GenerativeLossConfig(membrane=1.0),
        )


def test_warm_start_begins_from_the_given_weights(toy_dataset, tmp_path):
    quiet = dict(log=lambda *_: None, progress=False)
    train_generative(toy_dataset, tmp_path / "base", _config(epochs=2), **quiet)
    base = tmp_path / "base" / "checkpoint.pt"
    # one epoch at learning rate 0 from the base run's weights keeps them exactly
    train_generative(
        toy_dataset, tmp_path / "fine", _config(epochs=1, lr=0.0, init=str(base)), **quiet
    )
    a, b = (
        torch.load(p, weights_only=False)["model"]
        for p in (base, tmp_path / "fine" / "checkpoint.pt")
    )
    assert all(torch.equal(a[k], b[k]) for k in a)
    # ... and a fresh run does not start there
    train_generative(toy_dataset, tmp_path / "fresh", _config(epochs=1, lr=0.0), **quiet)
    c = torch.load(tmp_path / "fresh" / "checkpoint.pt", weights_only=False)["model"]
    assert not all(torch.equal(a[k], c[k]) for k in a)
    # another model configuration is refused by name
    other = _config(epochs=1, init=str(base))
    other.model = GenerativeConfig(uv_size=32, channels=(4, 8, 8, 16), rec_hidden=(16, 16, 16))
    with pytest.raises(LoosefitInputError, match="model_config"):
        train_generative(toy_dataset, tmp_path / "other", other, **quiet)


def test_a_basis_decoder_trains_from_its_projection_and_loads(toy_dataset, skirt, tmp_path):
    """Decoder "basis": the training frames' principal directions, kept in the checkpoint
    (a model without its data set), and the start is the projection onto them."""
    from loosefit.data.format import DatasetReader
    from loosefit.inference.checkpoints import load_generative
    from loosefit.model.engine import fit_basis
    from loosefit.train.frames import avatar_for, prepare_split

    quiet = dict(log=lambda *_: None, progress=False)
    cfg = _config(epochs=6, model=GenerativeConfig(decoder="basis", basis_size=3, **SMALL))
    start = train_generative(
        toy_dataset, tmp_path / "start", _config(**{**vars(cfg), "epochs": 1, "lr": 0.0}), **quiet
    )
    report = train_generative(toy_dataset, tmp_path / "b", cfg, **quiet)
    assert np.isfinite(report["test"]["rmse_cm"]) and start["train"]["rmse_cm"] < 0.01
    model, _ = load_generative(tmp_path / "b" / "checkpoint.pt", skirt)
    reader = DatasetReader(toy_dataset)
    frames = prepare_split(reader, "train", avatar_for(reader))
    want = fit_basis(frames.posed, 3)
    torch.testing.assert_close(model.basis_dirs, want.basis)
    torch.testing.assert_close(model.basis_mean, want.mean)
    # more directions than training frames: refused before any training, by name
    many = _config(epochs=1, model=GenerativeConfig(decoder="basis", basis_size=100, **SMALL))
    with pytest.raises(LoosefitInputError, match="basis_size.*at most the 32 training frames"):
        train_generative(toy_dataset, tmp_path / "many", many, **quiet)
    # the start: the projection onto the basis (a learning rate of 0 keeps it)
    first, _ = load_generative(tmp_path / "start" / "checkpoint.pt", skirt)
    c = torch.einsum("nvc,kvc->nk", frames.posed - want.mean, want.basis)
    projected = want.mean + torch.einsum("nk,kvc->nvc", c, want.basis)
    torch.testing.assert_close(first.reconstruct_all(frames.posed), projected, atol=1e-5, rtol=0)


def test_a_mirrored_run_trains_on_every_frame_and_its_mirror_image(toy_dataset, tmp_path):
    """``mirror`` doubles the training frames (each clip and itself mirrored), not the
    held-out ones, and its report scores each mirrored clip by name."""
    quiet = dict(log=lambda *_: None, progress=False)
    report = train_generative(toy_dataset, tmp_path / "m", _config(epochs=1, mirror=True), **quiet)
    assert report["train"]["frames"] == 64 and report["test"]["frames"] == 16
    assert {"a", "a~mirror", "b", "b~mirror"} <= set(report["train"]["clips"])
    _, cfg, _ = load_checkpoint(tmp_path / "m" / "checkpoint.pt")
    assert cfg.mirror is True
