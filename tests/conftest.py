"""Shared fixtures: one avatar per test session (building anny is the slow part)."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"
# A committed set with all three stages (generative, motion, detail): the salsa set, kept in
# the checkout. The shipped dance set has no detail stage (docs/results/DANCE_SETS.md), so the tests
# of a detail stage's files and graphs read this one.
WITH_DETAIL = REPO / "checkpoints" / "salsa"
SALSA = SHARED / "mocap" / "cmu-salsa"

needs_salsa = pytest.mark.skipif(
    not SALSA.is_dir(),
    reason="../shared/mocap/cmu-salsa (CMU salsa clips) is not present beside the repository",
)


def _workers(config) -> bool:
    """Whether this run spreads its tests over pytest-xdist workers and this process is the
    controller that starts them."""
    if getattr(config, "workerinput", None) is not None:
        return False
    return bool(config.pluginmanager.hasplugin("xdist") and config.getoption("numprocesses"))


def pytest_configure(config):
    """With several workers, anny's cache is built once here, before they start: anny writes
    its cache files without a lock, so two workers building it at once on a fresh machine could
    read each other's half-written file. A few seconds when the cache is there."""
    if not _workers(config):
        return
    import importlib.util

    if importlib.util.find_spec("anny") is None:
        return
    import warp

    warp.config.log_level = warp.LOG_WARNING  # the workers' own start-up says what warp found
    from loosefit.body.avatar import Avatar

    Avatar()


@pytest.fixture(scope="session")
def avatar():
    """The default avatar (anny, cmu_mb rig). The first run ever builds anny's cache (~2 min)."""
    from loosefit.body.avatar import Avatar

    return Avatar()


@pytest.fixture(scope="session")
def skirt(avatar):
    """A coarse skirt (96 vertices) for the learned stages' tests."""
    from loosefit.fitting.place import fit_skirt
    from loosefit.garment.skirt import SkirtConfig

    return fit_skirt(avatar, SkirtConfig(style="aline", rings=6, segments=16))


@pytest.fixture(scope="session")
def toy_dataset(avatar, skirt, tmp_path_factory):
    """Two train clips and one test clip: the skirt carried by the hips, swaying sideways."""
    import numpy as np

    from loosefit.data.format import FORMAT, write_json_atomic, write_sequence
    from loosefit.fitting.place import carry_rigidly
    from loosefit.motion.motions import load_motion
    from loosefit.sequence import GarmentSequence

    root = tmp_path_factory.mktemp("toy") / "ds"
    (root / "sequences").mkdir(parents=True)
    skirt.save(root / "template.npz")
    for name, move in (("a", "spin"), ("b", "kick"), ("c", "sway")):
        motion = load_motion(move, avatar).slice(10, 26)
        body = avatar.pose_motion(motion)
        g = carry_rigidly(skirt, body, avatar).numpy()
        depth = skirt.vertices[:, 2].max() - skirt.vertices[:, 2]  # 0 at the waist
        phase = np.sin(np.arange(len(g)) / 3.0)[:, None]
        g[..., 0] += 0.3 * depth[None] * phase  # the hem swings, the waist stays
        shape = {"rig": "cmu_mb", "shape": dict(avatar.shape)}
        write_sequence(
            root / "sequences" / f"{name}.npz", GarmentSequence(motion, skirt, g, shape, "toy")
        )
    from dataclasses import asdict

    from loosefit.sim.cloth_config import ClothConfig

    manifest = {
        "format": FORMAT,
        "complete": True,
        "config": {"cloth": asdict(ClothConfig.tiny())},
        "body": {"model": "anny", "rig": "cmu_mb", "shape": {}, "floor_height": 0.9},
        "split": {"train": ["a", "b"], "test": ["c"]},
    }
    write_json_atomic(root / "manifest.json", manifest)
    return root


@pytest.fixture(scope="session")
def tiny_simulated(avatar, tmp_path_factory):
    """The ``tiny`` preset's data set as the local runner makes it (one process, uninterrupted):
    simulated once a session; read it, or copy it to change it."""
    from loosefit.sim.generate import generate
    from loosefit.sim.presets import preset

    out = tmp_path_factory.mktemp("tiny_simulated") / "tiny"
    generate(preset("tiny"), out, workers=1, progress=False)
    return out
