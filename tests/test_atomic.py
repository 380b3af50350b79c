"""atomic_path: the file appears whole or not at all; an old file survives a failed write."""

from __future__ import annotations

import os

import numpy as np
import pytest

from loosefit.atomic import atomic_path
from loosefit.errors import LoosefitInputError


def test_the_file_appears_only_when_the_write_ends(tmp_path):
    target = tmp_path / "arrays.npz"
    with atomic_path(target) as tmp:
        assert tmp.parent == tmp_path and tmp.suffix == ".npz" and tmp != target
        np.savez(tmp, x=np.arange(3))  # a writer that picks its format by the suffix
        assert not target.exists()
    with np.load(target) as z:
        np.testing.assert_array_equal(z["x"], [0, 1, 2])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["arrays.npz"]  # nothing left beside


def test_a_failed_write_leaves_the_old_file_and_no_partial_one(tmp_path):
    target = tmp_path / "notes.txt"
    target.write_text("old")
    with pytest.raises(RuntimeError, match="disk full"):
        with atomic_path(target) as tmp:
            tmp.write_text("half of the n")
            raise RuntimeError("disk full")
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]


def test_a_missing_or_read_only_folder_is_refused_naming_the_path(tmp_path):
    missing = tmp_path / "no" / "such.npz"
    with pytest.raises(
        LoosefitInputError, match="expected a path in a writable folder, found no such folder"
    ) as e:
        with atomic_path(missing):
            pytest.fail("the body ran")
    assert e.value.source == str(missing)
    if os.geteuid() == 0:
        return  # root writes anywhere: a read-only folder is not one to it
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        with pytest.raises(LoosefitInputError, match="a folder that is not writable"):
            with atomic_path(locked / "x.txt"):
                pytest.fail("the body ran")
    finally:
        locked.chmod(0o700)
