"""A data set's clips (loosefit.sim.jobs): their names, splits and motions."""

from __future__ import annotations

import re

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.sim.dataset_config import DatasetConfig, MotionSource, read_config_file
from loosefit.sim.jobs import job_motion, plan_jobs, spec_name
from loosefit.sim.presets import preset
from tests.conftest import needs_salsa


def test_motions_as_specs_are_named_and_held_out_by_name(tmp_path):
    config = preset("tiny")
    config.motions = MotionSource(
        kind="specs", specs=("spin", "mirror:kick", "dance:2"), test=("mirror_kick",)
    )
    jobs = plan_jobs(config)
    assert [(j.name, j.spec, j.test) for j in jobs] == [
        ("spin", "spin", False),
        ("mirror_kick", "mirror:kick", True),
        ("dance_2", "dance:2", False),
    ]
    assert spec_name("speed:1.25:/data/mocap/61_01.bvh") == "speed_1.25_61_01"
    config.motions.test = ("nope",)
    with pytest.raises(LoosefitInputError, match="test.*names of the motions"):
        plan_jobs(config)
    config.motions = MotionSource(kind="specs", specs=("spin", "spin"))
    with pytest.raises(LoosefitInputError, match="distinct names"):
        plan_jobs(config)


def test_a_folder_of_mixed_motion_files_is_a_data_set_s_motions(tmp_path, avatar):
    """BVH, GLB, SMPL .npz and loosefit .npz files side by side, from the command line: each
    a clip named after its file, each read to the motion it was written from."""
    from loosefit.cli import build_parser
    from loosefit.cli.simulate import dataset_config
    from loosefit.motion.bvh import read_bvh
    from loosefit.motion.motions import load_motion
    from tests.motion.bvh_conventions import CONVENTIONS, motion_error, write_convention_bvh
    from tests.motion.gltf_writer import write_gltf
    from tests.motion.test_smpl import SMPL_MAP, smpl_arrays

    dance = load_motion("dance:2", avatar, seed=3)
    folder = tmp_path / "mocap"
    folder.mkdir()
    daz = CONVENTIONS["daz"]
    write_convention_bvh(folder / "a_studio.bvh", daz, avatar.skeleton, dance, avatar.floor_height)
    write_gltf(folder / "b_blender.glb", read_bvh(folder / "a_studio.bvh"))
    poses, trans = smpl_arrays(avatar, dance)
    np.savez(folder / "c_amass.npz", poses=poses, trans=trans, mocap_framerate=np.array(30.0))
    dance.save(folder / "d_loosefit.npz")
    (folder / "notes.txt").write_text("not a motion")
    args = build_parser().parse_args(
        ["simulate", "--preset", "tiny", "--motions", str(folder), "--test", "c_amass"]
    )
    jobs = plan_jobs(dataset_config(args))
    assert [(j.name, j.test) for j in jobs] == [
        ("a_studio", False),
        ("b_blender", False),
        ("c_amass", True),
        ("d_loosefit", False),
    ]
    cm = 0.01
    for job, joints in zip(jobs, (daz.joints, daz.joints, SMPL_MAP, None), strict=True):
        back = load_motion(job.spec, avatar)
        assert back.num_frames == dance.num_frames, job.name
        if joints is None:
            np.testing.assert_allclose(back.rotations, dance.rotations, atol=1e-6)
        else:
            mean, _ = motion_error(avatar, dance, back, joints)
            assert mean < 1 * cm, (job.name, mean)
    # refused, naming the files: one clip name twice, an .npz that is no motion
    dance.save(folder / "a_studio.npz")
    with pytest.raises(LoosefitInputError, match=r"a_studio.*a_studio\.bvh and a_studio\.npz"):
        plan_jobs(dataset_config(args))
    (folder / "a_studio.npz").unlink()
    np.savez(folder / "e_points.npz", positions=np.zeros((3, 3)))
    with pytest.raises(LoosefitInputError, match=r"e_points\.npz.*poses.*fields \['positions'\]"):
        plan_jobs(dataset_config(args))


@needs_salsa
@pytest.mark.parametrize("name, clips", [
    ("regression.yaml", {"frames_290_370_60_02": 80, "frames_290_370_mirror_60_02": 80,
                         "speed_1.5_frames_290_370_60_02": 53, "frames_150_220_60_01": 70,
                         "speed_1.5_spin": 86}),
    ("salsa_takes.yaml", {"60_01": 551, "60_02": 515, "speed_1.25_mirror_60_02": 410,
                          "speed_1.5_dance_20": 389}),
    ("salsa_turned.yaml", {"61_01": 551, "61_02": 515}),
])  # fmt: skip
def test_the_committed_penetration_sets_load_every_motion(name, clips, avatar):
    # bench/data/penetration_regression.py runs these (docs/design/PENETRATION.md): each spec
    # must still name a clip of ../shared and a window inside it, with the frame counts of the
    # tables.
    # The pose correction keeps the frame count (job_motion's docstring) and is tested on its
    # own (tests/motion/test_pose_correction.py): left out here, where it took most of CI's time.
    from pathlib import Path

    config = read_config_file(Path(__file__).parents[2] / "configs" / name)
    jobs = plan_jobs(config)
    assert [j.name for j in jobs] == list(clips)
    for job in jobs:
        motion = job_motion(config, job, avatar, unfold=False)
        assert motion.num_frames == clips[job.name], job.name


@needs_salsa
def test_a_job_simulates_the_squat_of_60_02_turned_out_of_the_belly(avatar):
    from tests.conftest import SALSA

    spec = f"frames:326:336:{SALSA / '60_02.bvh'}"  # the deepest of the squat
    config = DatasetConfig(motions=MotionSource(kind="specs", specs=(spec,)))
    job = plan_jobs(config)[0]
    motion = job_motion(config, job, avatar)
    record = motion.meta["unfold"]
    assert record["unfold_frames"] == 10 and record["unfold_degrees_max"] == pytest.approx(10.0)
    assert record["fold_depth_before"] > 0.03 > record["fold_depth_after"] > 0.01
    captured = job_motion(config, job, avatar, unfold=False)
    assert "unfold" not in captured.meta and captured.num_frames == motion.num_frames
    assert not np.array_equal(captured.rotations, motion.rotations)


def test_the_pose_correction_runs_on_the_simulation_s_device(avatar, monkeypatch):
    """A data set simulated on a GPU corrects its poses there too (the correction's queries
    are most of a clip's preparation on the CPU)."""
    import dataclasses

    import loosefit.motion.pose_correction as unfold

    seen = []
    real = unfold.unfold_motion

    def spy(*args, device="cpu", **kwargs):
        seen.append(device)
        return real(*args, **kwargs)

    monkeypatch.setattr(unfold, "unfold_motion", spy)
    config = preset("tiny")
    job = plan_jobs(config)[0]
    job_motion(config, job, avatar)
    gpu = dataclasses.replace(config, cloth=dataclasses.replace(config.cloth, device="cuda:0"))
    job_motion(gpu, job, avatar)
    assert seen == ["cpu", "cuda:0"]


def test_an_ensemble_is_each_clip_once_per_seed_with_the_clip_s_motion(avatar):
    from loosefit.sim.jobs import member_name, split_member

    config = preset("tiny")
    config.motions = MotionSource(kind="procedural", count=2, seconds=2.0, test_every=2)
    config.seed, config.seeds = 3, [3, 0, 7]
    jobs = plan_jobs(config)
    assert [(j.name, j.seed, j.jitter_seed, j.member_seed, j.test) for j in jobs] == [
        ("dance_000", 1003, 1003, 3, False),
        ("dance_000@seed0", 1003, 1000, 0, False),
        ("dance_000@seed7", 1003, 1007, 7, False),
        ("dance_001", 1004, 1004, 3, True),
        ("dance_001@seed0", 1004, 1001, 0, True),
        ("dance_001@seed7", 1004, 1008, 7, True),
    ]
    # the members' motion is the clip's, to the bit; the clips' dances differ
    first, *others = [job_motion(config, j, avatar, unfold=False) for j in jobs[:3]]
    for motion in others:
        np.testing.assert_array_equal(motion.rotations, first.rotations)
        np.testing.assert_array_equal(motion.root_translation, first.root_translation)
    assert job_motion(config, jobs[3], avatar, unfold=False).meta["moves"] != first.meta["moves"]
    # no seeds: today's clips, names and seeds; the member of the data set's seed is the clip
    config.seeds = None
    plain = plan_jobs(config)
    assert [(j.name, j.seed, j.jitter_seed, j.member_seed) for j in plain] == [
        ("dance_000", 1003, 1003, None),
        ("dance_001", 1004, 1004, None),
    ]
    assert [(j.name, j.seed, j.jitter_seed) for j in jobs[::3]] == [
        (j.name, j.seed, j.jitter_seed) for j in plain
    ]
    # the names, both ways
    assert member_name("05_02", 1, 0) == "05_02@seed1" and member_name("05_02", 0, 0) == "05_02"
    assert split_member("05_02@seed1") == ("05_02", 1) and split_member("05_02") == ("05_02", None)
    assert split_member("chain_a@seed12") == ("chain_a", 12)
    for name in ("a@seed", "a@seedx", "a@seed01", "@seed1", "a@seed-1"):
        assert split_member(name) == (name, None)


def test_a_clip_named_like_a_member_is_refused_in_an_ensemble(tmp_path):
    """A file ``take@seed1.bvh`` would read as the member of seed 1 of ``take``."""
    for name in ("take.bvh", "take@seed1.bvh"):
        (tmp_path / name).write_text("")  # planned, never read
    config = DatasetConfig(motions=MotionSource(kind="bvh", folder=str(tmp_path)))
    assert [j.name for j in plan_jobs(config)] == ["take", "take@seed1"]  # no ensemble: as ever
    config.seeds = [0, 1]
    with pytest.raises(LoosefitInputError, match=r"'seeds'.*@seedN.*'take@seed1'"):
        plan_jobs(config)


def test_an_ensemble_of_specs_seeds_each_member_as_a_data_set_of_its_seed_would():
    """``seeds: [1]`` jitters each clip of motion files as the data set of ``seed: 1`` did
    (the shared dance-seeds members, made so by hand); the motion files take no seed."""
    config = DatasetConfig(motions=MotionSource(kind="specs", specs=("a.bvh", "b.bvh")))
    config.seeds = [1]
    members = plan_jobs(config)
    by_hand = DatasetConfig(motions=config.motions, seed=1)
    assert [(j.name, j.spec, j.jitter_seed) for j in members] == [
        (f"{j.name}@seed1", j.spec, j.seed) for j in plan_jobs(by_hand)
    ]


@pytest.mark.parametrize("seeds, found", [
    ([], "an empty list"),
    ([0, 1, 0], r"0 twice in \[0, 1, 0\]"),
    ([2, -1], r"-1 in \[2, -1\]"),
    ([0, "a"], r"'a' in \[0, 'a'\]"),
    ([0, 1.5], r"1\.5 in \[0, 1\.5\]"),
    ("0,1", "'0,1'"),
])  # fmt: skip
def test_bad_ensemble_seeds_are_refused_before_any_simulation(seeds, found, tmp_path, monkeypatch):
    import yaml

    import loosefit.sim.workers as workers
    from loosefit.sim.generate import generate

    with pytest.raises(
        LoosefitInputError, match=rf"DatasetConfig: field 'seeds': expected .*{found}"
    ):
        DatasetConfig(seeds=seeds)
    (tmp_path / "c.yaml").write_text(yaml.safe_dump({"seeds": seeds}))
    with pytest.raises(LoosefitInputError, match=rf"c\.yaml: field 'seeds': expected .*{found}"):
        read_config_file(tmp_path / "c.yaml")
    config = preset("tiny")
    config.seeds = seeds  # set after the configuration was made: refused by the run
    monkeypatch.setattr(workers.Worker, "build", lambda *a, **k: pytest.fail("simulated"))
    with pytest.raises(LoosefitInputError, match=rf"field 'seeds': expected .*{found}"):
        generate(config, tmp_path / "out", workers=1, progress=False)
    assert not (tmp_path / "out").exists()


def test_simulate_seeds_on_the_command_line(tmp_path, capsys):
    from loosefit.cli import main

    cfg = tmp_path / "c.yaml"

    def write(*flags: str) -> int:
        return main(["simulate", "--preset", "tiny", *flags, "--write-config", str(cfg)])

    assert write("--seeds", "0, 1,3") == 0 and read_config_file(cfg).seeds == [0, 1, 3]
    assert write() == 0 and read_config_file(cfg).seeds is None
    for text, message in [
        ("0,a", r"--seeds: field 'seeds': expected comma-separated integers.*'a' in '0,a'"),
        ("1,2,1", r"--seeds: field 'seeds': expected distinct integers >= 0, found 1 twice"),
        ("", r"--seeds: field 'seeds': expected at least one seed.*found an empty list"),
        ("0,-2", r"found -2 in \[0, -2\]"),
    ]:
        assert write(f"--seeds={text}") == 2, text
        assert re.search(message, capsys.readouterr().err), text
