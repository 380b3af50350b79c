"""A data set's manifest (loosefit.sim.manifest): opened again by a later run; its migrations."""

from __future__ import annotations

import json

import pytest

from loosefit.errors import LoosefitInputError
from loosefit.sim.dataset_config import config_dict, normalized
from loosefit.sim.jobs import plan_jobs
from loosefit.sim.manifest import clip_entry, open_manifest, stored_config
from loosefit.sim.presets import preset


def test_a_data_set_begun_on_a_gpu_goes_on_on_the_cpu(tmp_path):
    """The device is no part of a data set's configuration: each clip's entry notes its
    own, the manifest keeps the first run's; the cloth fingerprint leaves it out."""
    from types import SimpleNamespace

    out = tmp_path / "ds"
    gpu = preset("tiny")
    gpu.cloth.device = "cuda:0"
    manifest = open_manifest(gpu, out)
    job = plan_jobs(gpu)[0]
    motion = SimpleNamespace(num_frames=5, meta={})
    manifest["sequences"][job.name] = clip_entry(gpu, job, motion, None, 1.0, "diverged")
    out.mkdir()
    (out / "manifest.json").write_text(json.dumps(manifest))
    cpu = preset("tiny")
    again = open_manifest(cpu, out)  # taken, not "another dataset"
    assert again["config"]["cloth"]["device"] == "cuda:0"  # the first run's
    entry, on_cpu = again["sequences"][job.name], clip_entry(cpu, job, motion, None)
    assert entry["device"] == "cuda:0" and on_cpu["device"] == "cpu"
    assert entry["cloth_fingerprint"] == on_cpu["cloth_fingerprint"]
    changed = preset("tiny")
    changed.cloth.iterations = 9  # any other change of the cloth is another data set
    with pytest.raises(LoosefitInputError, match=r"another dataset.*cloth"):
        open_manifest(changed, out)
    assert clip_entry(changed, job, motion, None)["cloth_fingerprint"] != entry["cloth_fingerprint"]


def test_entries_keep_the_manifest_s_fingerprint_when_a_field_is_added(tmp_path):
    """A data set written before a cloth field existed: its entries' fingerprint (of the
    configuration without the field) becomes the one of the configuration with it."""
    from loosefit.garment.fingerprint import cloth_fingerprint

    out = tmp_path / "ds"
    config = preset("tiny")
    manifest = open_manifest(config, out)
    del manifest["config"]["cloth"]["self_contact_rest_exclusion"]  # as if written before it
    old = cloth_fingerprint(manifest["config"]["cloth"])
    manifest["sequences"]["a"] = {"cloth_fingerprint": old}
    manifest["sequences"]["b"] = {"cloth_fingerprint": "another one"}
    out.mkdir()
    (out / "manifest.json").write_text(json.dumps(manifest))
    again = open_manifest(config, out)
    now = cloth_fingerprint(again["config"]["cloth"])
    assert now != old and again["sequences"]["a"]["cloth_fingerprint"] == now
    assert again["sequences"]["b"]["cloth_fingerprint"] == "another one"


def test_a_data_set_made_before_the_pose_correction_was_made_without_it():
    stored = normalized(config_dict(preset("tiny")))
    del stored["unfold"]
    assert stored_config({"config": stored})["unfold"]["enabled"] is False
    assert preset("salsa").unfold.enabled is True  # new data: the correction
