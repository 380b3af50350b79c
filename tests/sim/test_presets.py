"""The named data sets (loosefit.sim.presets) and the clips they make."""

from __future__ import annotations

import pytest

from loosefit.errors import LoosefitInputError
from loosefit.sim.dataset_config import read_config_file, write_config_file
from loosefit.sim.jobs import plan_jobs, short_spec
from loosefit.sim.presets import BALLET_CLIPS, BALLET_TEST, BALLET_TRAIN, PRESETS, preset


def _salsa_folder(tmp_path, names: tuple[str, ...]):
    """A ``cmu-salsa`` folder of empty BVH files named ``names`` (the jobs only read names)."""
    salsa = tmp_path / "cmu-salsa"
    salsa.mkdir()
    for name in names:
        (salsa / f"{name}.bvh").write_text("")
    return salsa


def test_unknown_preset_and_empty_bvh_folder(tmp_path):
    expected = (
        "one of tiny, demo, salsa, salsa-speed, salsa-speeds, dance, dance-speed, dance-pitch, "
        "dance-spin, dance-spins, dance-spins-slow, dance-turns, paper"
    )
    with pytest.raises(LoosefitInputError, match=expected):
        preset("huge")
    with pytest.raises(
        LoosefitInputError,
        match=r"motion files \(\.bvh, \.gltf, \.glb, \.npz\)"
        r".*no motion file",
    ):
        plan_jobs(preset("salsa", bvh_folder=str(tmp_path)))


def test_salsa_holds_out_its_test_clips_as_one_long_sequence(tmp_path):
    for name in ("60_01", "60_03", "61_03", "60_02"):
        (tmp_path / f"{name}.bvh").write_text("")
    cfg = preset("salsa", bvh_folder=str(tmp_path))
    jobs = plan_jobs(cfg)
    assert [(j.name, j.test) for j in jobs] == [
        ("60_01", False),
        ("60_02", False),
        ("chain_60_03_61_03", True),
    ]
    assert jobs[-1].spec == f"{tmp_path / '60_03.bvh'}+{tmp_path / '61_03.bvh'}"


def test_dance_is_salsa_and_the_ballet_clips_with_three_held_out(tmp_path):
    salsa = _salsa_folder(tmp_path, ("60_01", "60_03", "61_03", "60_02", "60_07", "61_07"))
    plain = plan_jobs(preset("salsa", bvh_folder=str(salsa)))
    cfg = preset("dance", bvh_folder=str(salsa))
    jobs = plan_jobs(cfg)
    assert jobs[: len(plain)] == plain  # the salsa clips and their held-out chain, as in salsa
    ballet = jobs[len(plain) :]
    assert [j.name for j in ballet] == list(BALLET_CLIPS)
    assert [j.name for j in ballet if j.test] == ["05_02", "05_10", "05_12"]
    assert ballet[0].spec == str(tmp_path / "cmu-ballet" / "05_01.bvh")
    assert len({j.seed for j in jobs}) == len(jobs)
    # the arms collide, as simulate's defaults do; salsa keeps them out as its data was made
    assert cfg.cloth.arm_friction == 0.0 and preset("salsa").cloth.arm_friction is None
    cfg.motions.test = (*cfg.motions.test, "05_99")
    with pytest.raises(LoosefitInputError, match="05_99"):
        plan_jobs(cfg)


def test_salsa_speed_adds_faster_training_clips_only(tmp_path):
    for name in ("60_01", "60_03", "61_03", "60_02"):
        (tmp_path / f"{name}.bvh").write_text("")
    plain = plan_jobs(preset("salsa", bvh_folder=str(tmp_path)))
    jobs = plan_jobs(preset("salsa-speed", bvh_folder=str(tmp_path)))
    assert jobs[: len(plain)] == plain  # the salsa clips, unchanged
    extra = jobs[len(plain) :]
    assert [(j.name, j.test) for j in extra] == [("60_01_x1.25", False), ("60_02_x1.25", False)]
    assert extra[0].spec == f"speed:1.25:{tmp_path / '60_01.bvh'}"
    assert short_spec(extra[0].spec) == "speed:1.25:60_01.bvh"
    assert len({j.seed for j in jobs}) == len(jobs)
    both = plan_jobs(preset("salsa-speeds", bvh_folder=str(tmp_path)))
    assert both[: len(jobs)] == jobs  # salsa-speed's clips, same seeds: --reuse takes them
    assert [j.name for j in both[len(jobs) :]] == ["60_01_x1.5", "60_02_x1.5"]
    assert len({j.seed for j in both}) == len(both)
    cfg = preset("salsa", bvh_folder=str(tmp_path))
    cfg.motions.speeds = (1.0,)
    with pytest.raises(LoosefitInputError, match="speeds"):
        plan_jobs(cfg)


def test_dance_speed_retimes_the_ballet_training_clips_only(tmp_path):
    salsa = _salsa_folder(tmp_path, ("60_01", "60_03", "61_03", "60_07", "61_07", "60_05"))
    dance = plan_jobs(preset("dance", bvh_folder=str(salsa)))
    jobs = plan_jobs(preset("dance-speed", bvh_folder=str(salsa)))
    assert jobs[: len(dance)] == dance  # the corpus's clips, same seeds: --reuse takes them
    extra = jobs[len(dance) :]
    assert [j.name for j in extra] == [f"{c}_x{s}" for s in ("1.25", "0.8") for c in BALLET_TRAIN]
    assert not any(j.test for j in extra)
    assert extra[0].spec == f"speed:1.25:{tmp_path / 'cmu-ballet' / '05_01.bvh'}"
    assert len({j.seed for j in jobs}) == len(jobs)
    # no salsa clip retimed: 60_05, a validation clip of the corpus, stays out of training
    assert not any(j.name.startswith("60_") and "_x" in j.name for j in jobs)
    assert not set(BALLET_TRAIN) & set(BALLET_TEST)


def test_retimed_clips_must_exist_and_not_be_held_out(tmp_path):
    for name in ("60_01", "60_03"):
        (tmp_path / f"{name}.bvh").write_text("")
    cfg = preset("salsa", bvh_folder=str(tmp_path))
    cfg.motions.speeds = (1.25,)
    cfg.motions.speed_clips = ("60_01",)
    assert [j.name for j in plan_jobs(cfg)][-1] == "60_01_x1.25"
    cfg.motions.speed_clips = ("60_09",)
    with pytest.raises(LoosefitInputError, match=r"speed_clips.*60_09"):
        plan_jobs(cfg)
    cfg.motions.speed_clips = ("60_03",)  # held out
    with pytest.raises(LoosefitInputError, match=r"speed_clips.*not held out.*60_03"):
        plan_jobs(cfg)


def test_dance_pitch_pitches_the_ballet_training_clips_only(tmp_path):
    salsa = _salsa_folder(tmp_path, ("60_01", "60_03", "61_03", "60_07", "61_07", "60_05"))
    dance = plan_jobs(preset("dance", bvh_folder=str(salsa)))
    jobs = plan_jobs(preset("dance-pitch", bvh_folder=str(salsa)))
    assert jobs[: len(dance)] == dance  # the corpus's clips, same seeds: --reuse takes them
    extra = jobs[len(dance) :]
    assert [j.name for j in extra] == [f"{c}_pitch{d}" for d in ("10", "-10") for c in BALLET_TRAIN]
    assert not any(j.test for j in extra)
    assert extra[0].spec == f"pitch:10:{tmp_path / 'cmu-ballet' / '05_01.bvh'}"
    assert short_spec(extra[-1].spec) == "pitch:-10:05_20.bvh"
    assert len({j.seed for j in jobs}) == len(jobs)


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("pitches", (0.0,), "degrees other than 0"),
        ("pitches", (50.0,), "from -45 to 45"),
        ("pitches", (float("nan"),), "degrees other than 0"),
        ("pitches", (5.0, 5.0), "distinct degrees"),
        ("pitch_clips", ("60_09",), r"pitch_clips.*60_09"),
        ("pitch_clips", ("60_03",), r"pitch_clips.*not held out.*60_03"),
    ],
)
def test_bad_pitches_are_refused_before_any_simulation(tmp_path, field, value, match):
    for name in ("60_01", "60_03"):
        (tmp_path / f"{name}.bvh").write_text("")
    cfg = preset("salsa", bvh_folder=str(tmp_path))
    cfg.motions.pitches = (10.0,)
    assert [j.name for j in plan_jobs(cfg)][-1] == "60_01_pitch10"  # every training clip
    setattr(cfg.motions, field, value)
    with pytest.raises(LoosefitInputError, match=match):
        plan_jobs(cfg)


def test_dance_spin_spins_the_ballet_training_clips_only(tmp_path):
    salsa = _salsa_folder(tmp_path, ("60_01", "60_03", "61_03", "60_07", "61_07", "60_05"))
    dance = plan_jobs(preset("dance", bvh_folder=str(salsa)))
    jobs = plan_jobs(preset("dance-spin", bvh_folder=str(salsa)))
    assert jobs[: len(dance)] == dance  # the corpus's clips, same seeds: --reuse takes them
    extra = jobs[len(dance) :]
    assert [j.name for j in extra] == [f"{c}_spin1" for c in BALLET_TRAIN]
    assert not any(j.test for j in extra)
    assert short_spec(extra[0].spec) == "spin:1:05_01.bvh"
    assert len({j.seed for j in jobs}) == len(jobs)
    spins = plan_jobs(preset("dance-spins", bvh_folder=str(salsa)))
    assert spins[: len(jobs)] == jobs  # dance-spin's clips, same seeds: --reuse takes them
    assert [j.name for j in spins[len(jobs) :]] == [f"{c}_spin0.5" for c in BALLET_TRAIN]
    slow = plan_jobs(preset("dance-spins-slow", bvh_folder=str(salsa)))
    assert slow[: len(spins)] == spins  # dance-spins's clips, same seeds: --reuse takes them
    added = slow[len(spins) :]
    assert [j.name for j in added] == [f"{c}_spin1_ramp0.8_hold0" for c in BALLET_TRAIN]
    assert short_spec(added[0].spec) == "spin:1,ramp=0.8,hold=0:05_01.bvh"
    assert len({j.seed for j in slow}) == len(slow)
    turns = plan_jobs(preset("dance-turns", bvh_folder=str(salsa)))
    assert turns[: len(slow)] == slow
    flicks = turns[len(slow) :]
    assert [j.name for j in flicks] == [f"{c}_spin2_ramp0.25_hold0" for c in BALLET_TRAIN]
    assert len({j.seed for j in turns}) == len(turns)


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("spins", (0.0,), "turns a second other than 0"),
        ("spins", (5.0,), "from -4 to 4"),
        ("spins", (float("inf"),), "turns a second other than 0"),
        ("spins", (1.0, 1.0), "distinct spins"),
        ("spins", (1.0, "1,ramp=0.4"), "distinct spins"),
        ("spins", ("1,ramp=0",), "a ramp from 0.1 to 2 s"),
        ("spins", ("1,wobble=2",), r"TURNS\[,ramp=SECONDS\]"),
        ("spin_clips", ("60_09",), r"spin_clips.*60_09"),
        ("spin_clips", ("60_03",), r"spin_clips.*not held out.*60_03"),
    ],
)
def test_bad_spins_are_refused_before_any_simulation(tmp_path, field, value, match):
    for name in ("60_01", "60_03"):
        (tmp_path / f"{name}.bvh").write_text("")
    cfg = preset("salsa", bvh_folder=str(tmp_path))
    cfg.motions.spins = (-1.5,)
    assert [j.name for j in plan_jobs(cfg)][-1] == "60_01_spin-1.5"  # every training clip
    setattr(cfg.motions, field, value)
    with pytest.raises(LoosefitInputError, match=match):
        plan_jobs(cfg)


@pytest.mark.parametrize("name", PRESETS)
def test_every_preset_is_a_configuration_file(name, tmp_path):
    config = preset(name, bvh_folder=str(tmp_path))
    path = write_config_file(config, tmp_path / f"{name}.yaml")
    assert read_config_file(path) == config
