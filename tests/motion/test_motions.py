import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.motion.chain import chain_motions
from loosefit.motion.mirror import mirror_motion
from loosefit.motion.motions import MAX_DANCE_SECONDS, load_motion
from loosefit.motion.procedural import named_motion, random_dance
from loosefit.motion.resample import resample_motion, retime_motion


def _same(a, b):
    assert a.joint_names == b.joint_names and a.fps == b.fps
    np.testing.assert_array_equal(a.rotations, b.rotations)
    np.testing.assert_array_equal(a.root_translation, b.root_translation)


def test_a_move_name_is_the_procedural_move(avatar):
    motion = load_motion("kick", avatar, fps=24, seed=3)
    _same(motion, named_motion("kick", avatar.joint_names, avatar.floor_height, 3, 24))


def test_a_dance_of_seconds_is_the_random_dance(avatar):
    motion = load_motion("dance:1.5", avatar, fps=20, seed=2)
    _same(motion, random_dance(avatar.joint_names, avatar.floor_height, 1.5, 2, 20))


def test_prefixes_mirror_retime_and_cut_the_motion_after_them(avatar):
    spin = load_motion("spin", avatar)
    _same(load_motion("mirror:spin", avatar), mirror_motion(spin))
    _same(load_motion("speed:2:spin", avatar), retime_motion(spin, 2.0))
    _same(load_motion("frames:2:10:spin", avatar), spin.slice(2, 10))
    _same(load_motion("frames:2:10:speed:0.5:spin", avatar), retime_motion(spin, 0.5).slice(2, 10))


def test_a_chain_seeds_its_parts_in_turn_and_keeps_max_frames(avatar):
    chain = load_motion("spin+kick", avatar, seed=5, max_frames=40)
    parts = [load_motion("spin", avatar, seed=5), load_motion("kick", avatar, seed=6)]
    _same(chain, chain_motions(parts).slice(0, 40))
    assert chain.num_frames == 40


def test_start_frame_and_max_frames_trim_the_motion(avatar):
    spin = load_motion("spin", avatar)
    _same(load_motion("spin", avatar, start_frame=5, max_frames=7), spin.slice(5, 12))
    _same(load_motion("spin", avatar, max_frames=10**6), spin)
    with pytest.raises(LoosefitInputError, match=rf"start_frame.*in \[0, {spin.num_frames}\)"):
        load_motion("spin", avatar, start_frame=spin.num_frames)


def test_a_saved_motion_is_read_back_and_resampled_to_the_rate_asked(avatar, tmp_path):
    spin = load_motion("spin", avatar).slice(0, 20)
    spin.save(tmp_path / "spin.npz")
    _same(load_motion(tmp_path / "spin.npz", avatar), spin)
    _same(load_motion(tmp_path / "spin.npz", avatar, fps=15), resample_motion(spin, 15))
    np.savez(tmp_path / "weights.npz", w=np.zeros(3))
    with pytest.raises(LoosefitInputError) as err:
        load_motion(tmp_path / "weights.npz", avatar)
    assert err.value.field == "rotations" and err.value.found == "fields ['w']"


@pytest.mark.parametrize(
    ("spec", "field"),
    [
        ("moonwalk", "spec"),
        ("walk.fbx", "spec"),
        ("dance:0", "dance:SECONDS"),
        (f"dance:{MAX_DANCE_SECONDS * 2}", "dance:SECONDS"),
        ("dance:long", "dance:SECONDS"),
        ("speed:20:spin", "speed:FACTOR:MOTION"),
        ("speed:fast:spin", "speed:FACTOR:MOTION"),
        ("pitch:90:spin", "pitch:DEGREES:MOTION"),
        ("pitch:up:spin", "pitch:DEGREES:MOTION"),
        ("pitch:10:", "pitch:DEGREES:MOTION"),
        ("spin:0:walk", "spin:TURNS:MOTION"),
        ("spin:9:walk", "spin:TURNS:MOTION"),
        ("spin:left:walk", "spin:TURNS:MOTION"),
        ("spin:1:", "spin:TURNS:MOTION"),
        ("spin:1,hold=-2:walk", "spin:TURNS:MOTION"),
        ("frames:5:5:spin", "frames:START:STOP:MOTION"),
        ("frames:0:100000:spin", "frames:START:STOP"),
        ("units:furlong:walk.bvh", "units:UNIT:MOTION"),
        ("scale:-1:walk.bvh", "scale:METRES_PER_UNIT:MOTION"),
        ("joint-map::walk.bvh", "joint-map:MAP:MOTION"),
        ("animation:run:", "animation:NAME:MOTION"),
    ],
)
def test_a_bad_spec_is_refused_naming_its_form(avatar, spec, field):
    with pytest.raises(LoosefitInputError) as err:
        load_motion(spec, avatar)
    assert err.value.field == field
