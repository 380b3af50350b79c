"""No file a user gives loosefit can run code when read: every reader refuses a pickle.

Each test plants a payload (an object whose unpickling would create a marker file) in one
kind of file and reads it through loosefit's own reader: a clear error, and no marker.
"""

from __future__ import annotations

import pathlib

import numpy as np
import pytest
import torch

from loosefit.errors import LoosefitInputError
from tests.conftest import WITH_DETAIL


class Payload:
    """Unpickling this creates ``marker``: what an attacker's file would run instead."""

    def __init__(self, marker: pathlib.Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (pathlib.Path.touch, (self.marker,))


@pytest.fixture
def marker(tmp_path):
    path = tmp_path / "ran"
    yield path
    assert not path.exists(), "the payload ran"


def _checkpoint(path, fmt: str, marker) -> pathlib.Path:
    torch.save({"format": fmt, "model": {"w": torch.zeros(2)}, "garment": Payload(marker)}, path)
    return path


@pytest.mark.parametrize(
    "fmt",
    ["loosefit.generative/1", "loosefit.motion/1", "loosefit.detail/1", "loosefit.baseline/1"],
)
def test_a_checkpoint_with_a_pickled_object_is_refused(tmp_path, marker, fmt):
    from loosefit import load
    from loosefit.inference.baseline import load_baseline
    from loosefit.inference.checkpoints import load_generative

    path = _checkpoint(tmp_path / "evil.pt", fmt, marker)
    for loader in (load, load_baseline, load_generative):
        with pytest.raises(LoosefitInputError, match=r"evil\.pt.*run code"):
            loader(path)


def test_the_cli_refuses_it_too(tmp_path, marker, capsys):
    from loosefit.cli import main

    path = _checkpoint(tmp_path / "evil.pt", "loosefit.motion/1", marker)
    assert main(["animate", str(path), "sway", "--frames", "2", "--out", str(tmp_path)]) == 2
    assert "run code" in capsys.readouterr().err


def _npz_with_payload(path, marker, **arrays) -> pathlib.Path:
    evil = np.empty(1, dtype=object)
    evil[0] = Payload(marker)
    np.savez(path, **arrays, vertices=evil)
    return path


def test_npz_files_with_a_pickled_object_are_refused(tmp_path, marker, skirt):
    from loosefit.data.format import read_sequence
    from loosefit.model.ssdr import SkinningDecomposition
    from loosefit.sequence import GarmentSequence
    from loosefit.types import GarmentTemplate, Motion

    readers = {
        "template": GarmentTemplate.load,
        "sequence": GarmentSequence.load,
        "motion": Motion.load,
        "clip": lambda p: read_sequence(p, skirt),
        "decomposition": SkinningDecomposition.load,
    }
    for name, read in readers.items():
        path = _npz_with_payload(
            tmp_path / f"{name}.npz", marker, format=np.array("loosefit.sequence/1")
        )
        with pytest.raises(LoosefitInputError, match=rf"{name}\.npz.*pickled object"):
            read(path)


def test_the_simulation_s_resume_file_is_never_unpickled(tmp_path, marker):
    from loosefit.sim.resume import read_resume

    path = _npz_with_payload(tmp_path / "resume.npz", marker, key=np.array("k"), frame=np.array(1))
    assert read_resume(path, "k", 10) is None  # an unreadable state: the run starts over


def test_a_newer_format_version_asks_for_an_upgrade(tmp_path, skirt):
    from loosefit.inference.checkpoints import read_checkpoint_file

    torch.save({"format": "loosefit.motion/2", "loosefit_version": "9.0"}, tmp_path / "new.pt")
    with pytest.raises(
        LoosefitInputError,
        match=r"new\.pt.*'loosefit.motion/1'.*'loosefit.motion/2', written by "
        r"loosefit 9\.0.*upgrade loosefit",
    ):
        read_checkpoint_file(tmp_path / "new.pt", "loosefit.motion/1")


def test_every_checkpoint_says_what_it_is():
    """Every committed set (the shipped one, with its engine tier and residual process, and
    the salsa set, which has all three stages):
    its format, the version that wrote it, the garment's fingerprint, and the networks'
    configuration."""
    from loosefit.api import pretrained_checkpoint
    from loosefit.inference.checkpoints import load_torch

    sets = {
        pretrained_checkpoint().parent: ("generative", "motion", "engine", "residual"),
        WITH_DETAIL: ("generative", "motion", "detail"),
    }
    for root, names in sets.items():
        assert sorted(p.stem for p in root.glob("*.pt")) == sorted(names)
        for name in names:
            data = load_torch(root / f"{name}.pt")
            assert data["format"] == f"loosefit.{name}/1" and data["loosefit_version"]
            # a residual process's configuration is its process's (size, memory, scale)
            assert data["process"]["config"] if name == "residual" else data["model_config"]
            garment = (
                data["fingerprints"]["garment"]
                if name in ("detail", "residual")
                else data["garment"]["fingerprint"]
            )
            assert len(garment) == 16
