"""Resume files and run keys (loosefit.sim.resume)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import loosefit.sim.resume as resume
from loosefit.fitting.place import fit_skirt
from loosefit.garment.skirt import SkirtConfig
from loosefit.sim.cloth_config import ClothConfig
from loosefit.sim.release import TrappedRelease
from loosefit.sim.resume import resumed_release

TINY_SKIRT = SkirtConfig(style="aline", rings=8, segments=24)


def test_a_saved_run_the_release_would_have_changed_starts_over():
    from tests.meshes import cube

    v, f = cube(1.0)
    collider = np.stack([v] * 4)  # two frames of preroll, two of motion
    garment = np.array([[[0.0, 0.0, 0.6]], [[0.0, 0.0, 0.2]]], np.float32)  # in, 0.3 m deep
    saved = {"frame": np.int64(3), "garment": garment, "release_depth": np.float64(np.nan)}
    zero = [np.zeros(4, np.int64)]
    config = ClothConfig.tiny(release_depth=0.05)
    args = ([collider], [_release(v, f)], 2, 1 / 30)
    assert resumed_release(saved, config, *args, released=zero)[0] is None
    # the same frames at 0.5 m of release depth: taken, with the anchor over the top face
    deep = ClothConfig.tiny(release_depth=0.5)
    release = _release(v, f, depth=0.5)
    kept, _ = resumed_release(saved, deep, [collider], [release], 2, 1 / 30, released=zero)
    assert kept is saved and (release.face >= 0).all()
    # a run saved with a release that moved cloth: not taken without it
    moved = {**saved, "release_depth": np.float64(0.05), "released_0": np.array([0, 0, 1, 0])}
    assert (
        resumed_release(moved, ClothConfig.tiny(), [collider], None, 2, 1 / 30, released=zero)[0]
        is None
    )


def test_a_field_at_its_value_from_before_it_existed_leaves_the_run_key(template, monkeypatch):

    body = np.zeros((3, 10, 3), np.float32)
    config = ClothConfig.tiny()
    before = resume.run_key(body, template, config)
    monkeypatch.setattr(resume, "RUN_KEY_SINCE", {"jitter": config.jitter})
    assert resume.run_key(body, template, config) != before  # the field left the key
    other = dataclasses.replace(config, jitter=2 * config.jitter)
    assert resume.run_key(body, template, other) != resume.run_key(body, template, config)
    # the release never enters it
    with_release = dataclasses.replace(config, release_depth=0.02)
    assert resume.run_key(body, template, with_release) == resume.run_key(body, template, config)


def test_the_run_key_leaves_the_device_out_and_a_cpu_run_keeps_its_key(tmp_path):
    """A clip begun with --device cuda:0 goes on from its resume file with --device cpu
    (and back); a run saved on the CPU before the device left the key still resumes."""
    from loosefit.types import GarmentTemplate

    v = np.arange(18, dtype=np.float32).reshape(6, 3) / 10
    f = np.array([[0, 1, 2], [2, 3, 4], [3, 4, 5]])
    template = GarmentTemplate(v, f, np.zeros((6, 2), np.float32) + 0.5, f, np.array([0, 1]))
    body = np.arange(4 * 10 * 3, dtype=np.float32).reshape(4, 10, 3) / 100  # (T, Vb, 3)
    on_gpu = resume.run_key(body, template, ClothConfig(device="cuda:0"))
    on_cpu = resume.run_key(body, template, ClothConfig(device="cpu"))
    assert on_gpu == on_cpu == "b6e1604ee06b5b4e5e3e21cb5cbdd8cc"  # the key before the change
    tiny = ClothConfig.tiny(device="cuda:0")
    assert resume.run_key(body, template, tiny) == "1d2b5c13b1c0a98b4e23565967ce6374"
    assert resume.run_key(body, template, dataclasses.replace(tiny, iterations=9)) != on_cpu
    # a field added since keeps the key at its old behaviour and changes it otherwise
    for change in (
        {"chebyshev_rho": 0.9},
        {"initial_guess": "adaptive"},
        {"substep_body_move": 0.01},
    ):
        other = resume.run_key(body, template, dataclasses.replace(tiny, **change))
        assert other != "1d2b5c13b1c0a98b4e23565967ce6374", change
    # the resume file a GPU run saved is the CPU run's
    path = tmp_path / "clip.npz"
    resume.write_resume(path, key=np.array(on_gpu), frame=np.int64(3), seconds=np.float64(1.0))
    assert resume.read_resume(path, on_cpu, total=10) is not None
    assert resume.read_resume(path, "another run", total=10) is None


@pytest.fixture(scope="module")
def template(avatar):
    """A coarse skirt (its vertices and faces are all a run key reads of it)."""
    return fit_skirt(avatar, TINY_SKIRT)


def _release(v, f, parts=None, n=1, depth=0.05):
    parts = np.zeros(len(v), np.int64) if parts is None else parts
    return TrappedRelease(v, (f,), parts, n, depth, 0.004)
