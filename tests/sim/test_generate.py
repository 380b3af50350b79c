import json
import re

import numpy as np
import pytest

import loosefit.sim.generate as gen
from loosefit.data.format import DatasetReader
from loosefit.errors import LoosefitInputError
from tests.conftest import needs_salsa


@pytest.fixture(scope="module")
def tiny_dataset(tmp_path_factory, avatar):
    out = tmp_path_factory.mktemp("ds") / "tiny"
    manifest = gen.generate(gen.preset("tiny"), out, workers=1, progress=False)
    return out, manifest


def test_tiny_dataset_is_complete_and_readable(tiny_dataset):
    out, manifest = tiny_dataset
    assert manifest["complete"] and manifest["summary"]["clips_ok"] == 2
    assert manifest["split"] == {"train": ["kick_000"], "test": ["spin_001"]}
    for key in ("torch", "newton", "warp-lang", "anny"):
        assert key in manifest["versions"]
    reader = DatasetReader(out)
    seq = reader.read("kick_000")
    assert seq.garment_vertices.shape == (12, reader.template.num_vertices, 3)
    assert np.isfinite(seq.garment_vertices).all()
    q = manifest["sequences"]["kick_000"]["quality"]
    assert q["inside_max"] <= 0.01 and q["nan_count"] == 0
    assert "kick_000" in gen.format_report(manifest)
    # each clip notes its device and cloth configuration, the manifest's
    from loosefit.garment.fingerprint import cloth_fingerprint

    ours = cloth_fingerprint(manifest["config"]["cloth"])
    assert {e["device"] for e in manifest["sequences"].values()} == {"cpu"}
    assert {e["cloth_fingerprint"] for e in manifest["sequences"].values()} == {ours}
    assert reader.training_clips("train") == ["kick_000"]


def test_report_shows_the_inside_mean_and_the_poses_that_fold(tiny_dataset):
    _, manifest = tiny_dataset
    manifest = json.loads(json.dumps(manifest))
    assert "loosefit diagnose" not in gen.format_report(manifest)  # the tiny moves never fold
    entry = manifest["sequences"]["kick_000"]
    entry.update(overlap_frames=21, overlap_depth_max=0.0348, unfold_frames=31,
                 unfold_degrees_max=10.0)  # fmt: skip
    entry["quality"]["inside_mean"] = 0.00103
    report = gen.format_report(manifest)
    row = next(line for line in report.splitlines() if line.startswith("kick_000"))
    assert "0.00103" in row and "21, 3.5 cm" in row and "31, 10.0 deg" in row
    assert "loosefit diagnose DATASET kick_000" in report
    long = {**entry, "spec": "x"}
    manifest["sequences"]["speed_1.25_mirror_60_02_long_name"] = long
    lines = gen.format_report(manifest).splitlines()
    assert len({line.index("train") for line in lines if " train " in line}) == 1  # aligned


def test_rerun_with_same_config_does_nothing(tiny_dataset, monkeypatch):
    out, _ = tiny_dataset
    calls = []
    monkeypatch.setattr(gen, "_run_group", lambda *a: calls.append(a) or [])
    before = (out / "sequences" / "kick_000.npz").stat().st_mtime_ns
    gen.generate(gen.preset("tiny"), out, workers=1, progress=False)
    assert calls == []
    assert (out / "sequences" / "kick_000.npz").stat().st_mtime_ns == before


def test_resume_after_interruption(tmp_path, monkeypatch, avatar):
    """A run killed after its first clip keeps it; the rerun only simulates the rest."""
    out = tmp_path / "ds"
    real = gen._run_group
    done = []

    def first_then_die(config, jobs, out_dir, *rest):
        (job,) = jobs
        if done:
            # A half-written file from the kill must never count as a sequence.
            (out / "sequences" / f"{job.name}.partial.npz").write_bytes(b"half")
            raise KeyboardInterrupt
        done.append(job.name)
        return real(config, jobs, out_dir, *rest)

    monkeypatch.setattr(gen, "_run_group", first_then_die)
    with pytest.raises(KeyboardInterrupt):
        gen.generate(gen.preset("tiny"), out, workers=1, progress=False)
    manifest = json.loads((out / "manifest.json").read_text())
    assert not manifest["complete"] and list(manifest["sequences"]) == ["kick_000"]
    with pytest.raises(LoosefitInputError, match="unfinished"):
        DatasetReader(out)

    resumed = []

    def spy(config, jobs, out_dir, *rest):
        resumed.extend(j.name for j in jobs)
        return real(config, jobs, out_dir, *rest)

    monkeypatch.setattr(gen, "_run_group", spy)
    manifest = gen.generate(gen.preset("tiny"), out, workers=1, progress=False)
    assert resumed == ["spin_001"]
    assert manifest["complete"] and not list(out.rglob("*partial*"))
    DatasetReader(out).read("spin_001")


def test_clips_simulated_in_a_batch_are_the_same_data_set(tiny_dataset, tmp_path):
    """``batch=2``: both clips as two worlds of one model, written and judged one by one."""
    out, single = tiny_dataset
    manifest = gen.generate(gen.preset("tiny"), tmp_path / "b", workers=1, progress=False,
                            batch=2)  # fmt: skip
    assert manifest["complete"] and manifest["split"] == single["split"]
    reader, alone = DatasetReader(tmp_path / "b"), DatasetReader(out)
    for name, entry in manifest["sequences"].items():
        assert entry["status"] == "done" and entry["batch"] == 2
        got, want = reader.read(name).garment_vertices, alone.read(name).garment_vertices
        assert got.shape == want.shape and np.isfinite(got).all()
        # the same clip, up to the other world's rounding (see tests/sim/test_cloth.py)
        assert np.linalg.norm(got - want, axis=-1).max() < 0.05
    assert manifest["summary"]["clips_per_hour"] > 0
    assert "clips per hour" in gen.format_report(manifest)
    assert not list((tmp_path / "b" / "resume").iterdir())  # the batch's state, removed
    with pytest.raises(LoosefitInputError, match="batch"):
        gen.generate(gen.preset("tiny"), tmp_path / "c", progress=False, batch=0)


def test_a_batch_with_a_diverging_clip_is_run_again_clip_by_clip(tmp_path, monkeypatch, avatar):
    real = gen.simulate_batch
    sizes = []

    def spin_explodes(avatar, template, motions, *a, **k):
        sizes.append(len(motions))
        if any(m.name.startswith("spin") for m in motions):
            raise gen.SimulationError("diverged at motion frame 3: 12 NaN vertices")
        return real(avatar, template, motions, *a, **k)

    monkeypatch.setattr(gen, "simulate_batch", spin_explodes)
    manifest = gen.generate(gen.preset("tiny"), tmp_path / "d", progress=False, batch=2)
    assert sizes == [2, 1, 1]
    assert manifest["sequences"]["kick_000"]["status"] == "done"
    assert manifest["sequences"]["spin_001"]["status"] == "flagged"
    assert "NaN" in manifest["sequences"]["spin_001"]["reason"]


def test_folder_with_another_dataset_is_rejected(tiny_dataset):
    out, _ = tiny_dataset
    other = gen.preset("tiny")
    other.seed = 7
    with pytest.raises(LoosefitInputError, match=r"another dataset.*seed"):
        gen.generate(other, out, workers=1, progress=False)


def test_non_dataset_folder_is_rejected(tmp_path):
    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(LoosefitInputError, match="empty or new folder"):
        gen.generate(gen.preset("tiny"), tmp_path, workers=1, progress=False)


def test_unknown_preset_and_empty_bvh_folder(tmp_path):
    expected = "one of tiny, demo, salsa, salsa-speed, salsa-speeds, dance, paper"
    with pytest.raises(LoosefitInputError, match=expected):
        gen.preset("huge")
    with pytest.raises(LoosefitInputError, match=r"motion files \(\.bvh, \.gltf, \.glb, \.npz\)"
                       r".*no motion file"):  # fmt: skip
        gen.plan_jobs(gen.preset("salsa", bvh_folder=str(tmp_path)))


def test_salsa_holds_out_its_test_clips_as_one_long_sequence(tmp_path):
    for name in ("60_01", "60_03", "61_03", "60_02"):
        (tmp_path / f"{name}.bvh").write_text("")
    cfg = gen.preset("salsa", bvh_folder=str(tmp_path))
    jobs = gen.plan_jobs(cfg)
    assert [(j.name, j.test) for j in jobs] == [
        ("60_01", False), ("60_02", False), ("chain_60_03_61_03", True),
    ]  # fmt: skip
    assert jobs[-1].spec == f"{tmp_path / '60_03.bvh'}+{tmp_path / '61_03.bvh'}"


def test_dance_is_salsa_and_the_ballet_clips_with_three_held_out(tmp_path):
    salsa = tmp_path / "cmu-salsa"
    salsa.mkdir()
    for name in ("60_01", "60_03", "61_03", "60_02", "60_07", "61_07"):
        (salsa / f"{name}.bvh").write_text("")
    plain = gen.plan_jobs(gen.preset("salsa", bvh_folder=str(salsa)))
    cfg = gen.preset("dance", bvh_folder=str(salsa))
    jobs = gen.plan_jobs(cfg)
    assert jobs[: len(plain)] == plain  # the salsa clips and their held-out chain, as in salsa
    ballet = jobs[len(plain) :]
    assert [j.name for j in ballet] == list(gen.BALLET_CLIPS)
    assert [j.name for j in ballet if j.test] == ["05_02", "05_10", "05_12"]
    assert ballet[0].spec == str(tmp_path / "cmu-ballet" / "05_01.bvh")
    assert len({j.seed for j in jobs}) == len(jobs)
    # the arms collide, as simulate's defaults do; salsa keeps them out as its data was made
    assert cfg.cloth.arm_friction == 0.0 and gen.preset("salsa").cloth.arm_friction is None
    cfg.motions.test = (*cfg.motions.test, "05_99")
    with pytest.raises(LoosefitInputError, match="05_99"):
        gen.plan_jobs(cfg)


def test_salsa_speed_adds_faster_training_clips_only(tmp_path):
    for name in ("60_01", "60_03", "61_03", "60_02"):
        (tmp_path / f"{name}.bvh").write_text("")
    plain = gen.plan_jobs(gen.preset("salsa", bvh_folder=str(tmp_path)))
    jobs = gen.plan_jobs(gen.preset("salsa-speed", bvh_folder=str(tmp_path)))
    assert jobs[: len(plain)] == plain  # the salsa clips, unchanged
    extra = jobs[len(plain) :]
    assert [(j.name, j.test) for j in extra] == [("60_01_x1.25", False), ("60_02_x1.25", False)]
    assert extra[0].spec == f"speed:1.25:{tmp_path / '60_01.bvh'}"
    assert gen.short_spec(extra[0].spec) == "speed:1.25:60_01.bvh"
    assert len({j.seed for j in jobs}) == len(jobs)
    both = gen.plan_jobs(gen.preset("salsa-speeds", bvh_folder=str(tmp_path)))
    assert both[: len(jobs)] == jobs  # salsa-speed's clips, same seeds: --reuse takes them
    assert [j.name for j in both[len(jobs) :]] == ["60_01_x1.5", "60_02_x1.5"]
    assert len({j.seed for j in both}) == len(both)
    cfg = gen.preset("salsa", bvh_folder=str(tmp_path))
    cfg.motions.speeds = (1.0,)
    with pytest.raises(LoosefitInputError, match="speeds"):
        gen.plan_jobs(cfg)


def test_a_dataset_made_before_a_field_existed_still_resumes(tiny_dataset, monkeypatch):
    out, _ = tiny_dataset
    manifest = json.loads((out / "manifest.json").read_text())
    del manifest["config"]["motions"]["speeds"]  # as written before speeds existed
    (out / "manifest.json").write_text(json.dumps(manifest))
    calls = []
    monkeypatch.setattr(gen, "_run_group", lambda *a: calls.append(a) or [])
    gen.generate(gen.preset("tiny"), out, workers=1, progress=False)
    assert calls == []
    changed = gen.preset("tiny")
    changed.motions.speeds = (2.0,)  # a value other than the default is another dataset
    with pytest.raises(LoosefitInputError, match=r"another dataset.*motions"):
        gen.generate(changed, out, workers=1, progress=False)


def test_a_data_set_begun_on_a_gpu_goes_on_on_the_cpu(tmp_path):
    """The device is no part of a data set's configuration: each clip's entry notes its
    own, the manifest keeps the first run's; the cloth fingerprint leaves it out."""
    from types import SimpleNamespace

    out = tmp_path / "ds"
    gpu = gen.preset("tiny")
    gpu.cloth.device = "cuda:0"
    manifest = gen._open_manifest(gpu, out)
    job = gen.plan_jobs(gpu)[0]
    motion = SimpleNamespace(num_frames=5, meta={})
    manifest["sequences"][job.name] = gen._entry(gpu, job, motion, None, 1.0, "diverged")
    out.mkdir()
    (out / "manifest.json").write_text(json.dumps(manifest))
    cpu = gen.preset("tiny")
    again = gen._open_manifest(cpu, out)  # taken, not "another dataset"
    assert again["config"]["cloth"]["device"] == "cuda:0"  # the first run's
    entry, on_cpu = again["sequences"][job.name], gen._entry(cpu, job, motion, None)
    assert entry["device"] == "cuda:0" and on_cpu["device"] == "cpu"
    assert entry["cloth_fingerprint"] == on_cpu["cloth_fingerprint"]
    changed = gen.preset("tiny")
    changed.cloth.iterations = 9  # any other change of the cloth is another data set
    with pytest.raises(LoosefitInputError, match=r"another dataset.*cloth"):
        gen._open_manifest(changed, out)
    assert gen._entry(changed, job, motion, None)["cloth_fingerprint"] != entry["cloth_fingerprint"]


def test_entries_keep_the_manifest_s_fingerprint_when_a_field_is_added(tmp_path):
    """A data set written before a cloth field existed: its entries' fingerprint (of the
    configuration without the field) becomes the one of the configuration with it."""
    from loosefit.garment.fingerprint import cloth_fingerprint

    out = tmp_path / "ds"
    config = gen.preset("tiny")
    manifest = gen._open_manifest(config, out)
    del manifest["config"]["cloth"]["self_contact_rest_exclusion"]  # as if written before it
    old = cloth_fingerprint(manifest["config"]["cloth"])
    manifest["sequences"]["a"] = {"cloth_fingerprint": old}
    manifest["sequences"]["b"] = {"cloth_fingerprint": "another one"}
    out.mkdir()
    (out / "manifest.json").write_text(json.dumps(manifest))
    again = gen._open_manifest(config, out)
    now = cloth_fingerprint(again["config"]["cloth"])
    assert now != old and again["sequences"]["a"]["cloth_fingerprint"] == now
    assert again["sequences"]["b"]["cloth_fingerprint"] == "another one"


@pytest.fixture
def spied_copy(tiny_dataset, tmp_path, monkeypatch):
    """A copy of the tiny data set, and the list of the clips simulated into it from now on."""
    import shutil

    out = tmp_path / "tiny"
    shutil.copytree(tiny_dataset[0], out)
    real, simulated = gen._run_group, []

    def spy(config, jobs, out_dir, *rest):
        simulated.extend(j.name for j in jobs)
        return real(config, jobs, out_dir, *rest)

    monkeypatch.setattr(gen, "_run_group", spy)
    return out, simulated


def test_a_new_release_depth_keeps_the_clips_it_never_acts_on(spied_copy):
    out, simulated = spied_copy
    cfg = gen.preset("tiny")
    cfg.cloth.release_depth = 0.02  # no cloth of the tiny clips is 2 cm inside: both kept
    manifest = gen.generate(cfg, out, workers=1, progress=False)
    assert simulated == [] and manifest["summary"]["clips_ok"] == 2
    assert {e["release_depth"] for e in manifest["sequences"].values()} == {0.02}
    DatasetReader(out).check_uniform(["kick_000", "spin_001"])  # kept: of the new cloth
    # a clip the release acted on is simulated again without it
    manifest["sequences"]["spin_001"]["released_frames"] = 3
    (out / "manifest.json").write_text(json.dumps(manifest))
    manifest = gen.generate(gen.preset("tiny"), out, workers=1, progress=False)
    assert simulated == ["spin_001"] and manifest["summary"]["clips_ok"] == 2
    assert manifest["sequences"]["spin_001"]["release_depth"] is None
    # any other change of the cloth is another data set
    other = gen.preset("tiny")
    other.cloth.release_depth, other.cloth.iterations = 0.02, 9
    with pytest.raises(LoosefitInputError, match=r"another dataset.*cloth"):
        gen.generate(other, out, workers=1, progress=False)


def test_reuse_takes_shared_clips_and_simulates_only_the_rest(tiny_dataset, tmp_path, monkeypatch):
    source, _ = tiny_dataset
    cfg = gen.preset("tiny")
    cfg.motions.moves = ("kick", "spin", "sway")  # kick_000 and spin_001 as in the source
    real, simulated = gen._run_group, []

    def spy(config, jobs, out_dir, *rest):
        simulated.extend(j.name for j in jobs)
        return real(config, jobs, out_dir, *rest)

    monkeypatch.setattr(gen, "_run_group", spy)
    manifest = gen.generate(cfg, tmp_path / "grown", workers=1, progress=False, reuse=source)
    assert simulated == ["sway_002"]
    assert manifest["split"] == {"train": ["kick_000", "sway_002"], "test": ["spin_001"]}
    assert manifest["sequences"]["kick_000"]["reused_from"] == str(source)
    DatasetReader(tmp_path / "grown").check_uniform(["kick_000", "sway_002"])
    a, b = source / "sequences" / "kick_000.npz", tmp_path / "grown" / "sequences" / "kick_000.npz"
    assert a.read_bytes() == b.read_bytes()
    DatasetReader(tmp_path / "grown").read("sway_002")

    # a clip flagged there is taken as flagged, not simulated again
    flagged = tmp_path / "flagged"
    flagged.mkdir()
    manifest = json.loads((source / "manifest.json").read_text())
    manifest["sequences"]["spin_001"].update(status="flagged", reason="NaN")
    (flagged / "manifest.json").write_text(json.dumps(manifest))
    (flagged / "sequences").mkdir()
    mine = {"sequences": {}}
    (tmp_path / "mine" / "sequences").mkdir(parents=True)
    taken = gen.adopt_clips(gen.preset("tiny"), gen.plan_jobs(gen.preset("tiny")), mine,
                            tmp_path / "mine", flagged)  # fmt: skip
    assert taken == ["spin_001"] and mine["sequences"]["spin_001"]["status"] == "flagged"

    other = gen.preset("tiny")
    other.cloth.iterations = 9
    with pytest.raises(LoosefitInputError, match=r"differs in \['cloth'\]"):
        gen.generate(other, tmp_path / "other", workers=1, progress=False, reuse=source)
    with pytest.raises(LoosefitInputError, match="no manifest.json"):
        gen.generate(cfg, tmp_path / "x", workers=1, progress=False, reuse=tmp_path / "none")


def test_summary_quality_covers_the_kept_clips_only():
    def entry(status, frames, inside, spf):
        q = {"inside_max": inside, "strain_p99": 0.05, "max_speed": 3.0, "nan_count": 0}
        return {"status": status, "frames": frames, "seconds_per_frame": spf, "quality": q}

    crashed = {"status": "flagged", "frames": 10, "reason": "NaN"}
    manifest = {"sequences": {"a": entry("done", 100, 0.01, 2.0),
                              "b": entry("flagged", 50, 0.40, 4.0), "c": crashed}}  # fmt: skip
    s = gen.summarize(manifest)
    assert s["clips"] == 3 and s["clips_ok"] == 1 and s["frames"] == 100
    assert s["inside_max"] == 0.01  # not the flagged clip's 0.40
    assert s["seconds_per_frame_mean"] == 3.0  # the cost counts every simulated clip


# -- any garment, any motions, a configuration file ------------------------------------------


def test_a_tiny_dress_dataset_simulates_held_by_its_top_band(tmp_path, avatar):
    out = tmp_path / "dress"
    manifest = gen.generate(gen.preset("dress-tiny"), out, workers=1, progress=False)
    assert manifest["complete"] and manifest["summary"]["clips_ok"] == 2
    reader = DatasetReader(out)
    assert reader.template.meta["kind"] == "dress" and reader.template.name == "dress_strapless"
    assert manifest["config"]["garment"]["type"] == "dress"
    assert manifest["config"]["cloth"]["arm_collision"] == "upper"
    seq = reader.read("spin_001")
    g = seq.garment_vertices
    assert np.isfinite(g).all() and g.shape[1] == reader.template.num_vertices
    # the top band stays at the chest as the body spins; the hem hangs below the hips
    top = g[:, reader.template.waist, 2].mean(1) + 0  # world heights
    assert np.ptp(top) < 0.05 and (g[:, :, 2].min(1) < top - 0.3).all()
    q = manifest["sequences"]["spin_001"]["quality"]
    assert q["penetration_max"] <= 0.01 and q["nan_count"] == 0


def test_a_dress_needs_the_upper_arms_in_its_collider(tmp_path):
    config = gen.preset("dress-tiny")
    config.cloth.arm_collision = False
    with pytest.raises(LoosefitInputError, match="arm_collision.*upper"):
        gen.generate(config, tmp_path / "x", workers=1, progress=False)


def test_motions_as_specs_are_named_and_held_out_by_name(tmp_path):
    config = gen.preset("tiny")
    config.motions = gen.MotionSource(kind="specs", specs=("spin", "mirror:kick", "dance:2"),
                                      test=("mirror_kick",))  # fmt: skip
    jobs = gen.plan_jobs(config)
    assert [(j.name, j.spec, j.test) for j in jobs] == [
        ("spin", "spin", False), ("mirror_kick", "mirror:kick", True),
        ("dance_2", "dance:2", False)]  # fmt: skip
    assert gen.spec_name("speed:1.25:/data/mocap/61_01.bvh") == "speed_1.25_61_01"
    config.motions.test = ("nope",)
    with pytest.raises(LoosefitInputError, match="test.*names of the motions"):
        gen.plan_jobs(config)
    config.motions = gen.MotionSource(kind="specs", specs=("spin", "spin"))
    with pytest.raises(LoosefitInputError, match="distinct names"):
        gen.plan_jobs(config)


def test_a_folder_of_mixed_motion_files_is_a_data_set_s_motions(tmp_path, avatar):
    """BVH, GLB, SMPL .npz and loosefit .npz files side by side, from the command line: each
    a clip named after its file, each read to the motion it was written from."""
    from loosefit.body.bvh import read_bvh
    from loosefit.body.motions import load_motion
    from loosefit.cli import build_parser
    from loosefit.cli.simulate import dataset_config
    from tests.body.bvh_conventions import CONVENTIONS, motion_error, write_convention_bvh
    from tests.body.gltf_writer import write_gltf
    from tests.body.test_smpl import SMPL_MAP, smpl_arrays

    dance = load_motion("dance:2", avatar, seed=3)
    folder = tmp_path / "mocap"
    folder.mkdir()
    daz = CONVENTIONS["daz"]
    write_convention_bvh(folder / "a_studio.bvh", daz, avatar.skeleton, dance,
                         avatar.floor_height)  # fmt: skip
    write_gltf(folder / "b_blender.glb", read_bvh(folder / "a_studio.bvh"))
    poses, trans = smpl_arrays(avatar, dance)
    np.savez(folder / "c_amass.npz", poses=poses, trans=trans, mocap_framerate=np.array(30.0))
    dance.save(folder / "d_loosefit.npz")
    (folder / "notes.txt").write_text("not a motion")
    args = build_parser().parse_args(["simulate", "--preset", "tiny", "--motions", str(folder),
                                      "--test", "c_amass"])  # fmt: skip
    jobs = gen.plan_jobs(dataset_config(args))
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
        gen.plan_jobs(dataset_config(args))
    (folder / "a_studio.npz").unlink()
    np.savez(folder / "e_points.npz", positions=np.zeros((3, 3)))
    with pytest.raises(LoosefitInputError, match=r"e_points\.npz.*poses.*fields \['positions'\]"):
        gen.plan_jobs(dataset_config(args))


@pytest.mark.parametrize("name", gen.PRESETS)
def test_every_preset_is_a_configuration_file(name, tmp_path):
    config = gen.preset(name, bvh_folder=str(tmp_path))
    path = gen.write_config_file(config, tmp_path / f"{name}.yaml")
    assert gen.read_config_file(path) == config


def test_a_configuration_file_in_toml_with_a_garment_file(tmp_path, avatar):
    import sys

    if sys.version_info < (3, 11):
        pytest.skip("TOML needs Python 3.11's tomllib")
    (tmp_path / "d.toml").write_text(
        'preset = "mine"\n[garment]\ntype = "file"\npath = "my.obj"\nunits = "cm"\n'
        '[motions]\nkind = "specs"\nspecs = ["spin", "kick"]\ntest = ["kick"]\n'
        '[cloth]\narm_collision = "upper"\n'
    )
    config = gen.read_config_file(tmp_path / "d.toml")
    assert isinstance(config.garment, gen.GarmentFile) and config.garment.units == "cm"
    assert config.motions.specs == ("spin", "kick") and config.motions.test == ("kick",)
    assert config.cloth.arm_collision == "upper"
    # a parametric garment from a resolution preset, overridden field by field
    (tmp_path / "s.yaml").write_text("garment: {type: dress, resolution: paper, length: 1.0}\n")
    g = gen.read_config_file(tmp_path / "s.yaml").garment
    assert (g.rings, g.length, g.style) == (68, 1.0, "straps")


@pytest.mark.parametrize("text, field", [
    ("garment: {type: coat}\n", "garment.type"),
    ("garment: {type: skirt, colour: red}\n", "garment.colour"),
    ("cloth: {substeps: -1}\n", "cloth.substeps"),
    ("motions: [1, 2]\n", "motions"),
    ("- just a list\n", "<file>"),
    ("garment: {type: skirt\n", "<file>"),
])  # fmt: skip
def test_a_bad_configuration_file_names_the_field(tmp_path, text, field):
    (tmp_path / "bad.yaml").write_text(text)
    with pytest.raises(LoosefitInputError, match=rf"bad\.yaml.*field '{re.escape(field)}"):
        gen.read_config_file(tmp_path / "bad.yaml")
    with pytest.raises(LoosefitInputError, match=r"suffix"):
        gen.read_config_file(_touch(tmp_path / "c.json"))


def _touch(path):
    path.write_text("{}")
    return path


def test_simulate_a_garment_file_on_named_motions_from_the_command_line(tmp_path, avatar):
    from loosefit.cli import main
    from loosefit.dress import fit_dress
    from loosefit.garment.dress import DressConfig
    from loosefit.garment.obj import write_obj

    dress = fit_dress(avatar, DressConfig(style="strapless", rings=10, segments=24, length=0.5))
    v = dress.vertices * 100.0  # centimetres, Y up: as a garment tool writes it
    write_obj(tmp_path / "my_dress.obj", np.stack([v[:, 0], v[:, 2], -v[:, 1]], 1), dress.faces,
              dress.uvs, dress.face_uvs)  # fmt: skip
    out = tmp_path / "ds"
    cfg = tmp_path / "mine.yaml"
    args = ["simulate", "--preset", "tiny", "--garment", str(tmp_path / "my_dress.obj"),
            "--kind", "dress", "--motions", "spin,kick", "--test", "kick"]  # fmt: skip
    assert main([*args, "--write-config", str(cfg)]) == 0  # a file to start from
    assert main(["simulate", "--config", str(cfg), "--out", str(out), "--workers", "1"]) == 0
    reader = DatasetReader(out)
    assert reader.split("train") == ["spin"] and reader.split("test") == ["kick"]
    assert np.abs(reader.template.vertices - dress.vertices).max() < 1e-3
    stored = json.loads((out / "manifest.json").read_text())["config"]
    assert stored["garment"]["type"] == "file" and stored["garment"]["kind"] == "dress"
    assert stored["cloth"]["arm_collision"] == "upper"


def test_the_example_configuration_reads_with_its_paths_beside_it():
    from pathlib import Path

    path = Path(__file__).parents[2] / "configs" / "my_garment.yaml"
    config = gen.read_config_file(path)
    assert config.garment.path == str(path.parent / "my_dress.obj")
    assert config.motions.specs[-1] == str(path.parent / "../shared/mocap/cmu-salsa/61_01.bvh")
    assert config.motions.specs[3] == "mirror:kick"
    names = [j.name for j in gen.plan_jobs(config)]
    assert names == ["dance_8", "spin", "twirl", "mirror_kick", "61_01"]
    assert [j.name for j in gen.plan_jobs(config) if j.test] == ["twirl"]


def test_the_collider_follows_the_garment_file_s_kind(tmp_path, avatar):
    import yaml

    from loosefit.cli import main
    from loosefit.dress import fit_dress, fit_skirt
    from loosefit.garment.dress import DressConfig
    from loosefit.garment.obj import write_obj

    for name, template, arms in (("skirt", fit_skirt(avatar), False),
                                 ("dress", fit_dress(avatar, DressConfig()), "upper")):  # fmt: skip
        write_obj(tmp_path / f"{name}.obj", template.vertices, template.faces)
        cfg = tmp_path / f"{name}.yaml"
        assert main(["simulate", "--garment", str(tmp_path / f"{name}.obj"),
                     "--write-config", str(cfg)]) == 0  # fmt: skip
        assert yaml.safe_load(cfg.read_text())["cloth"]["arm_collision"] == arms, name


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
    # bench/penetration_regression.py runs these (docs/PENETRATION.md): each spec must still
    # name a clip of ../shared and a window inside it, with the frame counts of the tables.
    # The pose correction keeps the frame count (job_motion's docstring) and is tested on its
    # own (tests/body/test_unfold.py): left out here, where it took most of CI's time.
    from pathlib import Path

    config = gen.read_config_file(Path(__file__).parents[2] / "configs" / name)
    jobs = gen.plan_jobs(config)
    assert [j.name for j in jobs] == list(clips)
    for job in jobs:
        motion = gen.job_motion(config, job, avatar, unfold=False)
        assert motion.num_frames == clips[job.name], job.name


def test_a_data_set_made_before_the_pose_correction_was_made_without_it():
    stored = gen._normalized(gen._config_dict(gen.preset("tiny")))
    del stored["unfold"]
    assert gen._stored_config({"config": stored})["unfold"]["enabled"] is False
    assert gen.preset("salsa").unfold.enabled is True  # new data: the correction


def test_the_pose_correction_is_configured_from_a_file(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("preset: x\nunfold:\n  max_degrees: 5\n  enabled: true\n")
    assert gen.read_config_file(path).unfold.max_degrees == 5.0
    path.write_text("preset: x\nunfold:\n  degrees: 5\n")
    with pytest.raises(LoosefitInputError, match="unfold.degrees"):
        gen.read_config_file(path)
    path.write_text("preset: x\nunfold:\n  max_degrees: -5\n")
    with pytest.raises(LoosefitInputError, match="unfold.max_degrees"):
        gen.read_config_file(path)


@needs_salsa
def test_a_job_simulates_the_squat_of_60_02_turned_out_of_the_belly(avatar):
    from tests.conftest import SALSA

    spec = f"frames:326:336:{SALSA / '60_02.bvh'}"  # the deepest of the squat
    config = gen.DatasetConfig(motions=gen.MotionSource(kind="specs", specs=(spec,)))
    job = gen.plan_jobs(config)[0]
    motion = gen.job_motion(config, job, avatar)
    record = motion.meta["unfold"]
    assert record["unfold_frames"] == 10 and record["unfold_degrees_max"] == pytest.approx(10.0)
    assert record["fold_depth_before"] > 0.03 > record["fold_depth_after"] > 0.01
    captured = gen.job_motion(config, job, avatar, unfold=False)
    assert "unfold" not in captured.meta and captured.num_frames == motion.num_frames
    assert not np.array_equal(captured.rotations, motion.rotations)


def test_keep_poses_simulates_the_capture_as_it_is(tmp_path):
    from loosefit.cli import main

    cfg = tmp_path / "c.yaml"
    assert main(["simulate", "--preset", "tiny", "--write-config", str(cfg)]) == 0
    assert gen.read_config_file(cfg).unfold.enabled is True
    assert main(["simulate", "--preset", "tiny", "--keep-poses", "--write-config", str(cfg)]) == 0
    assert gen.read_config_file(cfg).unfold.enabled is False


def test_a_new_pose_correction_keeps_the_clips_whose_motion_it_leaves(spied_copy, monkeypatch):
    out, simulated = spied_copy
    cfg = gen.preset("tiny")
    cfg.unfold.deep_degrees = 30.0  # no leg of the tiny clips folds 5 cm deep: both kept
    manifest = gen.generate(cfg, out, workers=1, progress=False)
    assert simulated == [] and manifest["summary"]["clips_ok"] == 2
    assert not any("unfold_config" in e for e in manifest["sequences"].values())
    assert manifest["config"]["unfold"]["deep_degrees"] == 30.0

    # a correction that changes a clip's motion (here: says it does): it is simulated again
    import loosefit.body.unfold as unfold

    seen = []

    def same(avatar, motion, parts, a, b):
        seen.append((motion.name, a.max_degrees, b.max_degrees))
        return "spin" not in motion.name

    monkeypatch.setattr(unfold, "same_correction", same)
    cfg.unfold.max_degrees = 20.0
    manifest = gen.generate(cfg, out, workers=1, progress=False)
    assert simulated == ["spin_001"] and manifest["summary"]["clips_ok"] == 2
    assert sorted(seen) == [("kick", 10.0, 20.0), ("spin", 10.0, 20.0)]
    # any other change besides it is another data set
    cfg.unfold.max_degrees, cfg.cloth.iterations = 25.0, 9
    with pytest.raises(LoosefitInputError, match=r"another dataset.*cloth"):
        gen.generate(cfg, out, workers=1, progress=False)


def test_the_data_set_s_garment_is_the_workers_whatever_the_caller_s_threads():
    # The avatar's rest shape differs in a float's last bit between torch thread counts;
    # generate builds template.npz on one thread, as the workers build the garment they
    # simulate, and gives the caller its thread count back.
    import torch

    from loosefit.body.avatar import Avatar, AvatarConfig

    config = gen.preset("tiny")
    threads = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        with gen.one_torch_thread():
            assert torch.get_num_threads() == 1
            avatar = Avatar(AvatarConfig(shape=dict(config.shape)))
            ours = gen.make_garment(config.garment, avatar).vertices
        assert torch.get_num_threads() == 2
        gen._worker_init(config, None)  # what a worker process does first
        np.testing.assert_array_equal(gen._WORKER["template"].vertices, ours)
    finally:
        gen._WORKER.clear()
        torch.set_num_threads(threads)
