"""A data set's configuration (loosefit.sim.dataset_config): files in, files out, and errors
that name the field."""

from __future__ import annotations

import re

import pytest

from loosefit.errors import LoosefitInputError
from loosefit.sim.dataset_config import GarmentFile, read_config_file
from loosefit.sim.jobs import plan_jobs


def test_a_configuration_file_in_toml_with_a_garment_file(tmp_path, avatar):
    import sys

    if sys.version_info < (3, 11):
        pytest.skip("TOML needs Python 3.11's tomllib")
    (tmp_path / "d.toml").write_text(
        'preset = "mine"\n[garment]\ntype = "file"\npath = "my.obj"\nunits = "cm"\n'
        '[motions]\nkind = "specs"\nspecs = ["spin", "kick"]\ntest = ["kick"]\n'
        '[cloth]\narm_collision = "upper"\n'
    )
    config = read_config_file(tmp_path / "d.toml")
    assert isinstance(config.garment, GarmentFile) and config.garment.units == "cm"
    assert config.motions.specs == ("spin", "kick") and config.motions.test == ("kick",)
    assert config.cloth.arm_collision == "upper"
    # a parametric garment from a resolution preset, overridden field by field
    (tmp_path / "s.yaml").write_text("garment: {type: dress, resolution: paper, length: 1.0}\n")
    g = read_config_file(tmp_path / "s.yaml").garment
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
        read_config_file(tmp_path / "bad.yaml")
    with pytest.raises(LoosefitInputError, match=r"suffix"):
        read_config_file(_touch(tmp_path / "c.json"))


def _touch(path):
    path.write_text("{}")
    return path


def test_the_example_configuration_reads_with_its_paths_beside_it():
    from pathlib import Path

    path = Path(__file__).parents[2] / "configs" / "my_garment.yaml"
    config = read_config_file(path)
    assert config.garment.path == str(path.parent / "my_dress.obj")
    assert config.motions.specs[-1] == str(path.parent / "../shared/mocap/cmu-salsa/61_01.bvh")
    assert config.motions.specs[3] == "mirror:kick"
    names = [j.name for j in plan_jobs(config)]
    assert names == ["dance_8", "spin", "twirl", "mirror_kick", "61_01"]
    assert [j.name for j in plan_jobs(config) if j.test] == ["twirl"]


def test_the_pose_correction_is_configured_from_a_file(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("preset: x\nunfold:\n  max_degrees: 5\n  enabled: true\n")
    assert read_config_file(path).unfold.max_degrees == 5.0
    path.write_text("preset: x\nunfold:\n  degrees: 5\n")
    with pytest.raises(LoosefitInputError, match="unfold.degrees"):
        read_config_file(path)
    path.write_text("preset: x\nunfold:\n  max_degrees: -5\n")
    with pytest.raises(LoosefitInputError, match="unfold.max_degrees"):
        read_config_file(path)
