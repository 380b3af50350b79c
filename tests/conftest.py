"""Shared fixtures: one avatar per test session (building anny is the slow part)."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"
SALSA = SHARED / "mocap" / "cmu-salsa"

needs_salsa = pytest.mark.skipif(
    not SALSA.is_dir(),
    reason="../shared/mocap/cmu-salsa (CMU salsa clips) is not present beside the repository",
)


@pytest.fixture(scope="session")
def avatar():
    """The default avatar (anny, cmu_mb rig). The first run ever builds anny's cache (~2 min)."""
    from loosefit.body.avatar import Avatar

    return Avatar()
