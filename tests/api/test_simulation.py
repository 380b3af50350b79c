"""Ground truth through the API (loosefit.api.simulation): a data set's configuration from
a preset and the choices over it, the data set simulated and its report, a garment
simulated on an avatar; each against the simulator's own functions called directly."""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.api.simulation import (
    dataset_config,
    parametric_garments,
    parse_seeds,
    simulate_dataset,
    simulate_garment,
    simulation_report,
    write_dataset_config,
)
from loosefit.errors import LoosefitInputError
from loosefit.sim.dataset_config import (
    GarmentFile,
    MotionSource,
    config_dict,
    read_config_file,
)
from loosefit.sim.presets import preset


def test_a_preset_as_it_is_is_the_preset_s_configuration():
    for name in ("tiny", "demo", "dress-tiny"):
        assert config_dict(dataset_config(preset=name)) == config_dict(preset(name))
    with pytest.raises(LoosefitInputError, match="--preset.*'nosuch'"):
        dataset_config(preset="nosuch")


def test_the_choices_go_over_the_preset():
    config = dataset_config(
        preset="tiny",
        garment="dress-strapless",
        motions="spin,kick,",
        test=["kick"],
        seeds=[0, 2],
        device="cuda:0",
        shape={"weight": 0.7},
        max_frames=12,
        keep_poses=True,
    )
    from loosefit.garment.dress import DressConfig

    expected = preset("tiny")  # the same choices made on the configuration by hand
    expected.garment = DressConfig.preset("cpu", "strapless")
    expected.cloth.arm_collision = "upper"  # a dress's bodice reaches the upper arms
    expected.motions = MotionSource(kind="specs", specs=("spin", "kick"), test=("kick",))
    expected.motions.max_frames = 12
    expected.seeds, expected.shape, expected.preset = [0, 2], {"weight": 0.7}, "custom"
    expected.cloth.device = "cuda:0"
    expected.unfold.enabled = False
    assert config_dict(config) == config_dict(expected)
    # the held-out clips alone keep the preset's motions; an empty shape is still a choice
    only_test = dataset_config(preset="tiny", test=("spin",), shape={})
    assert only_test.motions.moves == ("kick", "spin") and only_test.motions.test == ("spin",)
    assert only_test.shape == {} and only_test.preset == "custom"
    with pytest.raises(LoosefitInputError, match="seeds"):
        dataset_config(preset="tiny", seeds=[1, 1])


def test_a_folder_of_motions_and_a_skirt_style(tmp_path):
    config = dataset_config(preset="tiny", motions=str(tmp_path), garment="circle")
    assert config.motions == MotionSource(kind="bvh", folder=str(tmp_path.resolve()))
    assert config.garment.style == "circle" and config.cloth.arm_collision is False
    assert set(parametric_garments()) == {
        "aline",
        "flared",
        "circle",
        "dress",
        "dress-straps",
        "dress-strapless",
    }


def test_a_garment_file_with_straps_is_a_dress_and_brings_the_arms_in(avatar, tmp_path):
    from loosefit.fitting.place import fit_dress
    from loosefit.garment.dress import DressConfig
    from loosefit.garment.obj import write_obj

    coarse = {"rings": 12, "segments": 24, "strap_rows": 3, "strap_columns": 3}
    dress = fit_dress(avatar, DressConfig.preset("cpu", "straps", **coarse))
    path = tmp_path / "mine.obj"
    write_obj(path, dress.vertices, dress.faces)
    config = dataset_config(preset="tiny", garment=str(path), offset=(0.0, 0.0, 0.01), up="z")
    assert config.garment == GarmentFile(str(path.resolve()), None, "z", None, (0.0, 0.0, 0.01))
    assert config.cloth.arm_collision == "upper" and config.preset == "custom"
    # said to be a skirt, it is one: the arms stay out
    skirt = dataset_config(preset="tiny", garment=str(path), kind="skirt")
    assert skirt.garment.kind == "skirt" and skirt.cloth.arm_collision is False


def test_a_written_configuration_reads_back_as_the_same_data_set(tmp_path):
    config = dataset_config(preset="tiny", garment="dress", seeds=[0, 1], max_frames=5)
    path = write_dataset_config(config, tmp_path / "mine.yaml")
    assert path == tmp_path / "mine.yaml"
    assert config_dict(read_config_file(path)) == config_dict(config)
    assert config_dict(dataset_config(config_file=path)) == config_dict(config)
    with pytest.raises(LoosefitInputError, match="suffix"):
        write_dataset_config(config, tmp_path / "mine.json")


def test_seeds_are_distinct_whole_numbers_named_by_their_source():
    assert parse_seeds("0,1, 2,") == [0, 1, 2]
    with pytest.raises(LoosefitInputError, match=r"^--seeds: .*'x' in '0,x'"):
        parse_seeds("0,x", source="--seeds")
    with pytest.raises(LoosefitInputError, match="^seeds"):
        parse_seeds("1,1")  # the same seed twice
    with pytest.raises(LoosefitInputError):
        parse_seeds("-1")


def test_the_data_set_is_the_runner_s_with_the_cluster_asked_for(monkeypatch, tmp_path):
    import loosefit.sim.generate as generate_module
    from loosefit.sim.cluster import ClusterConfig

    calls = []
    monkeypatch.setattr(generate_module, "generate", lambda *a, **k: calls.append((a, k)) or {})
    config = dataset_config(preset="tiny")
    for cluster in (False, True, "head:6379"):
        simulate_dataset(
            config, tmp_path, workers=3, batch=2, save_every=7, reuse="x", cluster=cluster
        )
    assert [c[0] for c in calls] == [(config, tmp_path)] * 3
    wanted = {"workers": 3, "progress": True, "reuse": "x", "batch": 2, "resume_every": 7}
    assert all({k: c[1][k] for k in wanted} == wanted for c in calls)
    assert [c[1]["cluster"] for c in calls] == [
        None,
        ClusterConfig(address=None),
        ClusterConfig(address="head:6379"),
    ]


def test_the_report_is_the_simulator_s():
    from loosefit.sim.report import format_report

    q = {"inside_max": 0.01, "strain_p99": 0.05, "max_speed": 3.0, "nan_count": 0}
    manifest = {
        "sequences": {
            "spin": {"status": "done", "frames": 12, "seconds_per_frame": 2.0, "quality": q},
            "kick": {"status": "flagged", "frames": 12, "test": True, "reason": "NaN"},
        },
        "split": {"train": ["spin"], "test": []},
    }
    text = simulation_report(manifest)
    assert text == format_report(manifest) and "spin" in text and "kick" in text


def test_a_garment_simulated_on_the_avatar_as_the_driver_does(monkeypatch, avatar):
    """The physics handed to the simulator: the default, with the device, the seed and the
    arms the garment needs."""
    import loosefit.sim.driver as driver
    from loosefit.fitting.place import fit_dress
    from loosefit.garment.dress import DressConfig
    from loosefit.motion.motions import load_motion
    from loosefit.sim.cloth_config import ClothConfig

    calls = []
    monkeypatch.setattr(driver, "simulate", lambda *a, **k: calls.append((a, k)) or "result")
    dress = fit_dress(avatar, DressConfig.preset("cpu", "straps", rings=12, segments=24))
    motion = load_motion("spin", avatar).slice(0, 3)
    seen = []
    out = simulate_garment(avatar, dress, motion, device="cuda:0", seed=4, progress=seen.append)
    assert out == "result"
    ((args, kwargs),) = calls
    assert args[0] is avatar and args[1] is dress and args[2] is motion
    assert args[3] == ClothConfig(device="cuda:0", seed=4, arm_collision="upper")
    assert kwargs == {"progress": seen.append}


@pytest.mark.heavy
def test_a_simulated_data_set_is_the_runner_s(tiny_simulated, tmp_path):
    """The tiny preset simulated through the API: the runner's data set, array for array."""
    from loosefit.data.format import DatasetReader

    manifest = simulate_dataset(dataset_config(preset="tiny"), tmp_path / "tiny", progress=False)
    assert manifest["complete"]
    ours, theirs = DatasetReader(tmp_path / "tiny"), DatasetReader(tiny_simulated)
    assert ours.split("all") == theirs.split("all")
    for name in ours.split("all"):
        a, b = ours.read(name), theirs.read(name)
        np.testing.assert_array_equal(a.garment_vertices, b.garment_vertices)
        np.testing.assert_array_equal(a.motion.rotations, b.motion.rotations)
