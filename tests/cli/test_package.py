"""``loosefit package``: a model's stages in one folder, through loosefit.api.package."""

from __future__ import annotations

import numpy as np

import loosefit
from loosefit.cli import main
from tests.conftest import WITH_DETAIL


def test_package_writes_the_set_and_it_animates_as_the_original(tmp_path, capsys):
    out = tmp_path / "set"
    argv = ["package", str(WITH_DETAIL / "motion.pt"), "--detail", str(WITH_DETAIL / "detail.pt")]
    assert main([*argv, "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["detail.pt", "generative.pt", "motion.pt"]
    said = capsys.readouterr().err
    assert f"wrote {out / 'motion.pt'}" in said and " MB)" in said
    a = loosefit.load(out).animate("sway", frames=3).vertices
    b = loosefit.load(WITH_DETAIL).animate("sway", frames=3).vertices
    np.testing.assert_array_equal(a, b)


def test_package_of_another_stage_is_refused_naming_it(tmp_path, capsys):
    out = tmp_path / "set"
    assert main(["package", str(WITH_DETAIL / "detail.pt"), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "loosefit: error:" in err and "'loosefit.motion/1'" in err
