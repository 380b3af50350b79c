"""The data set runner (loosefit.sim.generate): tiny data sets simulated, resumed, reused, rerun."""

from __future__ import annotations

import json

import numpy as np
import pytest

import loosefit.sim.workers as workers
from loosefit.data.format import FORMAT, DatasetReader
from loosefit.errors import LoosefitInputError
from loosefit.sim.dataset_config import config_dict, normalized, read_config_file
from loosefit.sim.driver import SimulationError
from loosefit.sim.generate import generate
from loosefit.sim.jobs import plan_jobs
from loosefit.sim.manifest import adopt_clips
from loosefit.sim.presets import preset
from loosefit.sim.report import format_report


@pytest.fixture(scope="module")
def tiny_dataset(tmp_path_factory, tiny_simulated):
    """This module's copy of the session's tiny data set (its tests change it), and its
    manifest."""
    import shutil

    out = tmp_path_factory.mktemp("ds") / "tiny"
    shutil.copytree(tiny_simulated, out)
    return out, json.loads((out / "manifest.json").read_text())


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
    assert "kick_000" in format_report(manifest)
    # each clip notes its device and cloth configuration, the manifest's
    from loosefit.garment.fingerprint import cloth_fingerprint

    ours = cloth_fingerprint(manifest["config"]["cloth"])
    assert {e["device"] for e in manifest["sequences"].values()} == {"cpu"}
    assert {e["cloth_fingerprint"] for e in manifest["sequences"].values()} == {ours}
    assert reader.training_clips("train") == ["kick_000"]


def test_the_data_set_records_its_rest_drape(tiny_dataset):
    from loosefit.body.avatar import Avatar, AvatarConfig
    from loosefit.sim.driver import settle
    from loosefit.sim.workers import one_torch_thread

    out, _ = tiny_dataset
    cfg = preset("tiny")
    reader = DatasetReader(out)
    with one_torch_thread():
        body = Avatar(AvatarConfig(shape=dict(cfg.shape)))
        want = settle(body, reader.template, cfg.cloth, cfg.fps)
    # the settle phase, once: the same machine and inputs, so the same numbers (1e-6 m: far
    # below any drape's seed spread, docs/design/TEST_TOLERANCES.md)
    np.testing.assert_allclose(reader.rest_drape, want, atol=1e-6)
    assert np.abs(want - reader.template.vertices).max() > 1e-3  # settled, not the template


def test_a_damaged_rest_drape_is_refused_naming_the_file(tiny_dataset, tmp_path):
    import shutil

    out = tmp_path / "copy"
    shutil.copytree(tiny_dataset[0], out)
    np.save(out / "rest_drape.npy", np.zeros((5, 3), np.float32))
    with pytest.raises(LoosefitInputError, match=r"rest_drape\.npy.*\(5, 3\)"):
        _ = DatasetReader(out).rest_drape
    bad = DatasetReader(out).template.vertices.copy()
    bad[0, 0] = np.nan
    np.save(out / "rest_drape.npy", bad)
    with pytest.raises(LoosefitInputError, match="NaN"):
        _ = DatasetReader(out).rest_drape


def test_report_shows_the_inside_mean_and_the_poses_that_fold(tiny_dataset):
    _, manifest = tiny_dataset
    manifest = json.loads(json.dumps(manifest))
    assert "loosefit diagnose" not in format_report(manifest)  # the tiny moves never fold
    entry = manifest["sequences"]["kick_000"]
    entry.update(
        overlap_frames=21, overlap_depth_max=0.0348, unfold_frames=31, unfold_degrees_max=10.0
    )
    entry["quality"]["inside_mean"] = 0.00103
    report = format_report(manifest)
    row = next(line for line in report.splitlines() if line.startswith("kick_000"))
    assert "0.00103" in row and "21, 3.5 cm" in row and "31, 10.0 deg" in row
    assert "loosefit diagnose DATASET kick_000" in report
    long = {**entry, "spec": "x"}
    manifest["sequences"]["speed_1.25_mirror_60_02_long_name"] = long
    lines = format_report(manifest).splitlines()
    assert len({line.index("train") for line in lines if " train " in line}) == 1  # aligned


def test_rerun_with_same_config_does_nothing(tiny_dataset, monkeypatch):
    out, _ = tiny_dataset
    calls = []
    monkeypatch.setattr(workers.Worker, "run", lambda *a: calls.append(a) or [])
    before = (out / "sequences" / "kick_000.npz").stat().st_mtime_ns
    generate(preset("tiny"), out, workers=1, progress=False)
    assert calls == []
    assert (out / "sequences" / "kick_000.npz").stat().st_mtime_ns == before


@pytest.mark.heavy
def test_resume_after_interruption(tmp_path, monkeypatch, avatar):
    """A run killed after its first clip keeps it; the rerun only simulates the rest."""
    out = tmp_path / "ds"
    real = workers.Worker.run
    done = []

    def first_then_die(worker, jobs, out_dir, *rest):
        (job,) = jobs
        if done:
            # A half-written file from the kill must never count as a sequence.
            (out / "sequences" / f"{job.name}.partial.npz").write_bytes(b"half")
            raise KeyboardInterrupt
        done.append(job.name)
        return real(worker, jobs, out_dir, *rest)

    monkeypatch.setattr(workers.Worker, "run", first_then_die)
    with pytest.raises(KeyboardInterrupt):
        generate(preset("tiny"), out, workers=1, progress=False)
    manifest = json.loads((out / "manifest.json").read_text())
    assert not manifest["complete"] and list(manifest["sequences"]) == ["kick_000"]
    with pytest.raises(LoosefitInputError, match="unfinished"):
        DatasetReader(out)

    resumed = []

    def spy(worker, jobs, out_dir, *rest):
        resumed.extend(j.name for j in jobs)
        return real(worker, jobs, out_dir, *rest)

    monkeypatch.setattr(workers.Worker, "run", spy)
    manifest = generate(preset("tiny"), out, workers=1, progress=False)
    assert resumed == ["spin_001"]
    assert manifest["complete"] and not list(out.rglob("*partial*"))
    DatasetReader(out).read("spin_001")


@pytest.mark.heavy
def test_clips_simulated_in_a_batch_are_the_same_data_set(
    tiny_dataset, tmp_path, monkeypatch, avatar
):
    """``batch=2``: both clips as two worlds of one model, written and judged one by one;
    their motions prepared in other processes before the batch, the same to the bit as a
    worker's own, and handed to a pool of simulation workers."""
    import dataclasses

    import loosefit.sim.generate as gen
    from loosefit.sim.driver import simulate
    from tests.sim.spread import mean_gap, seed_bound

    out, single = tiny_dataset
    prepared = []
    real = gen.prepare_motions

    def spy(config, jobs, processes, on_done=None):
        prepared.append(([j.name for j in jobs], processes))
        return real(config, jobs, processes, on_done)

    monkeypatch.setattr(gen, "prepare_motions", spy)
    manifest = generate(
        preset("tiny"), tmp_path / "b", workers=2, progress=False, batch=2, prepare_workers=2
    )
    assert [sorted(names) for names, _ in prepared] == [["kick_000", "spin_001"]]
    assert prepared[0][1] == 2
    assert manifest["complete"] and manifest["split"] == single["split"]
    reader, alone = DatasetReader(tmp_path / "b"), DatasetReader(out)
    for name, entry in manifest["sequences"].items():
        assert entry["status"] == "done" and entry["batch"] == 2
        got, want = reader.read(name).motion, alone.read(name).motion  # what was simulated
        np.testing.assert_array_equal(got.rotations, want.rotations)
        np.testing.assert_array_equal(got.root_translation, want.root_translation)
        got, want = reader.read(name).garment_vertices, alone.read(name).garment_vertices
        assert got.shape == want.shape and np.isfinite(got).all()
    # The batch's first world (kick_000: clips of one length go by name) sits where the clip
    # would alone: the very same numbers. The second is moved metres away: the same clip up
    # to the rounding there, within the spread of its jitter drawn with another seed,
    # measured here (tests/sim/spread.py; tests/sim/test_driver.py's batch).
    np.testing.assert_array_equal(
        reader.read("kick_000").garment_vertices, alone.read("kick_000").garment_vertices
    )
    spin = alone.read("spin_001")
    cloth = dataclasses.replace(
        preset("tiny").cloth, seed=single["sequences"]["spin_001"]["seed"] + 1
    )
    reseeded = simulate(avatar, alone.template, spin.motion, cloth).garment_vertices
    spread = mean_gap(reseeded, spin.garment_vertices)
    gap = mean_gap(reader.read("spin_001").garment_vertices, spin.garment_vertices)
    assert gap < seed_bound(spread), f"{gap * 1000:.1f} mm (seed: {spread * 1000:.1f} mm)"
    assert manifest["summary"]["clips_per_hour"] > 0
    assert "clips per hour" in format_report(manifest)
    assert not list((tmp_path / "b" / "resume").iterdir())  # the batch's state, removed
    with pytest.raises(LoosefitInputError, match="batch"):
        generate(preset("tiny"), tmp_path / "c", progress=False, batch=0)
    with pytest.raises(LoosefitInputError, match="prepare_workers"):
        generate(preset("tiny"), tmp_path / "c", progress=False, batch=2, prepare_workers=0)


@pytest.mark.heavy
def test_a_batch_with_a_diverging_clip_is_run_again_clip_by_clip(tmp_path, monkeypatch, avatar):
    real = workers.simulate_batch
    sizes = []

    def spin_explodes(avatar, template, motions, *a, **k):
        sizes.append(len(motions))
        if any(m.name.startswith("spin") for m in motions):
            raise SimulationError("diverged at motion frame 3: 12 NaN vertices")
        return real(avatar, template, motions, *a, **k)

    monkeypatch.setattr(workers, "simulate_batch", spin_explodes)
    manifest = generate(preset("tiny"), tmp_path / "d", progress=False, batch=2, prepare_workers=1)
    assert sizes == [2, 1, 1]
    assert manifest["sequences"]["kick_000"]["status"] == "done"
    assert manifest["sequences"]["spin_001"]["status"] == "flagged"
    assert "NaN" in manifest["sequences"]["spin_001"]["reason"]


def test_folder_with_another_dataset_is_rejected(tiny_dataset):
    out, _ = tiny_dataset
    other = preset("tiny")
    other.seed = 7
    with pytest.raises(LoosefitInputError, match=r"another dataset.*seed"):
        generate(other, out, workers=1, progress=False)


def test_non_dataset_folder_is_rejected(tmp_path):
    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(LoosefitInputError, match="empty or new folder"):
        generate(preset("tiny"), tmp_path, workers=1, progress=False)


def test_a_dataset_made_before_a_field_existed_still_resumes(tiny_dataset, monkeypatch):
    out, _ = tiny_dataset
    manifest = json.loads((out / "manifest.json").read_text())
    del manifest["config"]["motions"]["speeds"]  # as written before speeds existed
    (out / "manifest.json").write_text(json.dumps(manifest))
    calls = []
    monkeypatch.setattr(workers.Worker, "run", lambda *a: calls.append(a) or [])
    generate(preset("tiny"), out, workers=1, progress=False)
    assert calls == []
    changed = preset("tiny")
    changed.motions.speeds = (2.0,)  # a value other than the default is another dataset
    with pytest.raises(LoosefitInputError, match=r"another dataset.*motions"):
        generate(changed, out, workers=1, progress=False)


@pytest.fixture
def spied_copy(tiny_dataset, tmp_path, monkeypatch):
    """A copy of the tiny data set, and the list of the clips simulated into it from now on."""
    import shutil

    out = tmp_path / "tiny"
    shutil.copytree(tiny_dataset[0], out)
    real, simulated = workers.Worker.run, []

    def spy(worker, jobs, out_dir, *rest):
        simulated.extend(j.name for j in jobs)
        return real(worker, jobs, out_dir, *rest)

    monkeypatch.setattr(workers.Worker, "run", spy)
    return out, simulated


@pytest.mark.heavy
def test_a_new_release_depth_keeps_the_clips_it_never_acts_on(spied_copy):
    out, simulated = spied_copy
    cfg = preset("tiny")
    cfg.cloth.release_depth = 0.02  # no cloth of the tiny clips is 2 cm inside: both kept
    manifest = generate(cfg, out, workers=1, progress=False)
    assert simulated == [] and manifest["summary"]["clips_ok"] == 2
    assert {e["release_depth"] for e in manifest["sequences"].values()} == {0.02}
    DatasetReader(out).check_uniform(["kick_000", "spin_001"])  # kept: of the new cloth
    # a clip the release acted on is simulated again without it
    manifest["sequences"]["spin_001"]["released_frames"] = 3
    (out / "manifest.json").write_text(json.dumps(manifest))
    manifest = generate(preset("tiny"), out, workers=1, progress=False)
    assert simulated == ["spin_001"] and manifest["summary"]["clips_ok"] == 2
    assert manifest["sequences"]["spin_001"]["release_depth"] is None
    # any other change of the cloth is another data set
    other = preset("tiny")
    other.cloth.release_depth, other.cloth.iterations = 0.02, 9
    with pytest.raises(LoosefitInputError, match=r"another dataset.*cloth"):
        generate(other, out, workers=1, progress=False)


@pytest.mark.heavy
def test_reuse_takes_shared_clips_and_simulates_only_the_rest(tiny_dataset, tmp_path, monkeypatch):
    source, _ = tiny_dataset
    cfg = preset("tiny")
    cfg.motions.moves = ("kick", "spin", "sway")  # kick_000 and spin_001 as in the source
    real, simulated = workers.Worker.run, []

    def spy(worker, jobs, out_dir, *rest):
        simulated.extend(j.name for j in jobs)
        return real(worker, jobs, out_dir, *rest)

    monkeypatch.setattr(workers.Worker, "run", spy)
    manifest = generate(cfg, tmp_path / "grown", workers=1, progress=False, reuse=source)
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
    taken = adopt_clips(preset("tiny"), plan_jobs(preset("tiny")), mine, tmp_path / "mine", flagged)
    assert taken == ["spin_001"] and mine["sequences"]["spin_001"]["status"] == "flagged"

    other = preset("tiny")
    other.cloth.iterations = 9
    with pytest.raises(LoosefitInputError, match=r"differs in \['cloth'\]"):
        generate(other, tmp_path / "other", workers=1, progress=False, reuse=source)
    with pytest.raises(LoosefitInputError, match="no manifest.json"):
        generate(cfg, tmp_path / "x", workers=1, progress=False, reuse=tmp_path / "none")


def test_reuse_knows_a_motion_folder_by_where_it_is_not_how_it_is_written(tmp_path, monkeypatch):
    """A data set made with ``../shared/mocap/x`` lends its clips to one that names the same
    folder by its absolute path (a preset's default); another folder is refused."""
    (tmp_path / "shared" / "mocap" / "x").mkdir(parents=True)
    (tmp_path / "shared" / "mocap" / "y").mkdir()
    (tmp_path / "main").mkdir()
    monkeypatch.chdir(tmp_path / "main")
    theirs = preset("tiny")
    theirs.motions.folder = "../shared/mocap/x"
    source = tmp_path / "source"
    source.mkdir()
    manifest = {"format": FORMAT, "config": normalized(config_dict(theirs)), "sequences": {}}
    (source / "manifest.json").write_text(json.dumps(manifest))
    ours = preset("tiny")
    ours.motions.folder = str(tmp_path / "shared" / "mocap" / "x")
    mine = {"sequences": {}}
    assert adopt_clips(ours, plan_jobs(ours), mine, tmp_path / "mine", source) == []
    ours.motions.folder = str(tmp_path / "shared" / "mocap" / "y")
    with pytest.raises(LoosefitInputError, match=r"differs in \['motions.folder'\]"):
        adopt_clips(ours, plan_jobs(ours), mine, tmp_path / "mine", source)


@pytest.mark.heavy
def test_an_ensemble_simulates_each_clip_once_per_seed_and_resumes(
    tiny_dataset, tmp_path, monkeypatch
):
    """``seeds: [0, 1]`` on the tiny kick, held out: the member of seed 0 is the clip itself
    (the very frames of the tiny data set's kick_000), the other ``kick_000@seed1``: the same
    motion, the cloth's start jittered from seed 1, held out too. A run killed after its
    first member goes on with the other; a finished one simulates nothing; another data set
    takes the members it shares."""
    out = tmp_path / "ens"
    cfg = preset("tiny")
    cfg.motions.moves, cfg.motions.test_every, cfg.seeds = ("kick",), 1, [0, 1]
    real_run, real_batch = workers.Worker.run, workers.simulate_batch
    runs, seeds = [], {}  # the units run, and the jitter seeds the simulator was given

    def run(worker, jobs, out_dir, *rest):
        if len(runs) == 1:
            raise KeyboardInterrupt  # killed after its first member
        runs.append([j.name for j in jobs])
        return real_run(worker, jobs, out_dir, *rest)

    def batch(avatar, template, motions, *args, **kwargs):
        seeds.update(zip(runs[-1], kwargs["seeds"], strict=True))
        return real_batch(avatar, template, motions, *args, **kwargs)

    monkeypatch.setattr(workers.Worker, "run", run)
    monkeypatch.setattr(workers, "simulate_batch", batch)
    with pytest.raises(KeyboardInterrupt):
        generate(cfg, out, workers=1, progress=False)
    assert list(json.loads((out / "manifest.json").read_text())["sequences"]) == ["kick_000"]
    runs.append("killed")
    manifest = generate(cfg, out, workers=1, progress=False)
    assert runs == [["kick_000"], "killed", ["kick_000@seed1"]]
    assert manifest["complete"] and manifest["summary"]["clips_ok"] == 2
    assert manifest["split"] == {"train": [], "test": ["kick_000", "kick_000@seed1"]}
    assert seeds == {"kick_000": 1000, "kick_000@seed1": 1001}  # the clip's, and one more
    for s, name in ((0, "kick_000"), (1, "kick_000@seed1")):
        entry = manifest["sequences"][name]
        assert (entry["seed"], entry["motion_seed"]) == (1000 + s, 1000)
        assert (entry["member_seed"], entry["member_of"]) == (s, "kick_000")
    reader = DatasetReader(out)
    own, other = reader.read("kick_000"), reader.read("kick_000@seed1")
    np.testing.assert_array_equal(own.motion.rotations, other.motion.rotations)
    np.testing.assert_array_equal(own.motion.root_translation, other.motion.root_translation)
    gap = np.abs(own.garment_vertices - other.garment_vertices).max()
    assert gap > 1e-4, f"the members' cloth {gap * 1000:.3f} mm apart"  # 4 mm here
    alone = DatasetReader(tiny_dataset[0]).read("kick_000").garment_vertices
    np.testing.assert_array_equal(own.garment_vertices, alone)
    assert "member_seed" not in tiny_dataset[1]["sequences"]["kick_000"]  # no ensemble: as ever

    # finished: nothing simulated again
    runs.clear()
    monkeypatch.setattr(workers.Worker, "run", lambda *a: runs.append(a) or [])
    assert generate(cfg, out, workers=1, progress=False)["complete"] and runs == []
    # an ensemble of seeds 1 and 2 takes the member of seed 1 (named so in both)
    cfg.seeds = [1, 2]
    mine = {"sequences": {}}
    (tmp_path / "mine" / "sequences").mkdir(parents=True)
    assert adopt_clips(cfg, plan_jobs(cfg), mine, tmp_path / "mine", out) == ["kick_000@seed1"]
    assert mine["sequences"]["kick_000@seed1"]["member_of"] == "kick_000"
    # a data set of no ensemble takes the clip's own member, without the member's keys
    cfg.seeds, mine = None, {"sequences": {}}
    (tmp_path / "plain" / "sequences").mkdir(parents=True)
    assert adopt_clips(cfg, plan_jobs(cfg), mine, tmp_path / "plain", out) == ["kick_000"]
    assert not {"member_seed", "member_of", "motion_seed"} & set(mine["sequences"]["kick_000"])


@pytest.mark.heavy
def test_a_tiny_dress_dataset_simulates_held_by_its_top_band(tmp_path, avatar):
    out = tmp_path / "dress"
    manifest = generate(preset("dress-tiny"), out, workers=1, progress=False)
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
    config = preset("dress-tiny")
    config.cloth.arm_collision = False
    with pytest.raises(LoosefitInputError, match="arm_collision.*upper"):
        generate(config, tmp_path / "x", workers=1, progress=False)


@pytest.mark.heavy
def test_simulate_a_garment_file_on_named_motions_from_the_command_line(tmp_path, avatar):
    from loosefit.cli import main
    from loosefit.fitting.place import fit_dress
    from loosefit.garment.dress import DressConfig
    from loosefit.garment.obj import write_obj

    dress = fit_dress(avatar, DressConfig(style="strapless", rings=10, segments=24, length=0.5))
    v = dress.vertices * 100.0  # centimetres, Y up: as a garment tool writes it
    write_obj(
        tmp_path / "my_dress.obj",
        np.stack([v[:, 0], v[:, 2], -v[:, 1]], 1),
        dress.faces,
        dress.uvs,
        dress.face_uvs,
    )
    out = tmp_path / "ds"
    cfg = tmp_path / "mine.yaml"
    args = [
        "simulate",
        "--preset",
        "tiny",
        "--garment",
        str(tmp_path / "my_dress.obj"),
        "--kind",
        "dress",
        "--motions",
        "spin,kick",
        "--test",
        "kick",
    ]
    assert main([*args, "--write-config", str(cfg)]) == 0  # a file to start from
    assert main(["simulate", "--config", str(cfg), "--out", str(out), "--workers", "1"]) == 0
    reader = DatasetReader(out)
    assert reader.split("train") == ["spin"] and reader.split("test") == ["kick"]
    assert np.abs(reader.template.vertices - dress.vertices).max() < 1e-3
    stored = json.loads((out / "manifest.json").read_text())["config"]
    assert stored["garment"]["type"] == "file" and stored["garment"]["kind"] == "dress"
    assert stored["cloth"]["arm_collision"] == "upper"


def test_the_collider_follows_the_garment_file_s_kind(tmp_path, avatar):
    import yaml

    from loosefit.cli import main
    from loosefit.fitting.place import fit_dress, fit_skirt
    from loosefit.garment.dress import DressConfig
    from loosefit.garment.obj import write_obj

    for name, template, arms in (
        ("skirt", fit_skirt(avatar), False),
        ("dress", fit_dress(avatar, DressConfig()), "upper"),
    ):
        write_obj(tmp_path / f"{name}.obj", template.vertices, template.faces)
        cfg = tmp_path / f"{name}.yaml"
        assert (
            main(
                ["simulate", "--garment", str(tmp_path / f"{name}.obj"), "--write-config", str(cfg)]
            )
            == 0
        )
        assert yaml.safe_load(cfg.read_text())["cloth"]["arm_collision"] == arms, name


def test_keep_poses_simulates_the_capture_as_it_is(tmp_path):
    from loosefit.cli import main

    cfg = tmp_path / "c.yaml"
    assert main(["simulate", "--preset", "tiny", "--write-config", str(cfg)]) == 0
    assert read_config_file(cfg).unfold.enabled is True
    assert main(["simulate", "--preset", "tiny", "--keep-poses", "--write-config", str(cfg)]) == 0
    assert read_config_file(cfg).unfold.enabled is False


@pytest.mark.heavy
def test_a_new_pose_correction_keeps_the_clips_whose_motion_it_leaves(spied_copy, monkeypatch):
    out, simulated = spied_copy
    cfg = preset("tiny")
    cfg.unfold.deep_degrees = 30.0  # no leg of the tiny clips folds 5 cm deep: both kept
    manifest = generate(cfg, out, workers=1, progress=False)
    assert simulated == [] and manifest["summary"]["clips_ok"] == 2
    assert not any("unfold_config" in e for e in manifest["sequences"].values())
    assert manifest["config"]["unfold"]["deep_degrees"] == 30.0

    # a correction that changes a clip's motion (here: says it does): it is simulated again
    import loosefit.motion.pose_correction as unfold

    seen = []

    def same(avatar, motion, parts, a, b):
        seen.append((motion.name, a.max_degrees, b.max_degrees))
        return "spin" not in motion.name

    monkeypatch.setattr(unfold, "same_correction", same)
    cfg.unfold.max_degrees = 20.0
    manifest = generate(cfg, out, workers=1, progress=False)
    assert simulated == ["spin_001"] and manifest["summary"]["clips_ok"] == 2
    assert sorted(seen) == [("kick", 10.0, 20.0), ("spin", 10.0, 20.0)]
    # any other change besides it is another data set
    cfg.unfold.max_degrees, cfg.cloth.iterations = 25.0, 9
    with pytest.raises(LoosefitInputError, match=r"another dataset.*cloth"):
        generate(cfg, out, workers=1, progress=False)


@pytest.mark.heavy
def test_settled_once_the_clips_start_from_the_data_set_s_drape(tmp_path, monkeypatch):
    import dataclasses

    given = []
    real = workers.simulate_batch

    def spy(*args, **kwargs):
        given.append(kwargs.get("drape"))
        return real(*args, **kwargs)

    monkeypatch.setattr(workers, "simulate_batch", spy)
    cfg = preset("tiny")
    cfg = dataclasses.replace(cfg, cloth=dataclasses.replace(cfg.cloth, settle_once=True))
    out = tmp_path / "once"
    manifest = generate(cfg, out, workers=1, progress=False)
    assert manifest["complete"] and manifest["summary"]["clips_ok"] == 2
    drape = DatasetReader(out).rest_drape
    assert len(given) == 2 and all(np.array_equal(g, drape) for g in given)


def test_a_batch_holds_clips_of_similar_length(monkeypatch):
    from types import SimpleNamespace

    import loosefit.sim.generate as gen
    from loosefit.sim.jobs import Job

    frames = {"chain": 2000, "a": 550, "b": 500, "c": 300, "d": 260, "e": 150}
    monkeypatch.setattr(
        gen, "job_motion", lambda c, j, a, unfold: SimpleNamespace(num_frames=frames[j.name])
    )
    jobs = [Job(n, n, 0, False) for n in frames]
    groups, _ = gen._units(preset("tiny"), jobs, None, batch=3)
    assert [[j.name for j in g] for g in groups] == [["chain"], ["a", "b", "c"], ["d", "e"]]
    groups, _ = gen._units(preset("tiny"), jobs, None, batch=1)
    assert len(groups) == len(frames)
