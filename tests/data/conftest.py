"""The shared dance corpus (../shared/datasets/dance.lfz.*), unpacked once per session."""

from __future__ import annotations

import json

import pytest

from tests.conftest import REPO, SHARED

CORPUS = SHARED / "datasets"
DANCE_PACK = CORPUS / "dance.lfz."  # the common prefix of its pieces
LFZ = CORPUS / "lfz.py"  # the packer it was made with

needs_corpus = pytest.mark.skipif(
    not (CORPUS / "dance.lfz.000").is_file(),
    reason="../shared/datasets (the shared dance corpus, dance.lfz.*) is not present beside "
    "the repository",
)


@pytest.fixture(scope="session")
def dance_unpacked(tmp_path_factory):
    """The dance corpus as `loosefit dataset unpack` makes it, into a temporary folder."""
    if not (CORPUS / "dance.lfz.000").is_file():
        pytest.skip("../shared/datasets (the shared dance corpus) is not present")
    from loosefit.data.pack import unpack

    dest = tmp_path_factory.mktemp("corpus") / "dance"
    unpack(DANCE_PACK, dest)
    return dest


@pytest.fixture(scope="session")
def dance_dataset(request):
    """The dance corpus: the repository's datasets/dance when it is there and complete
    (every clip of its split on disk), else unpacked once into a temporary folder."""
    local = REPO / "datasets" / "dance"
    try:
        manifest = json.loads((local / "manifest.json").read_text())
        split = manifest["split"]["train"] + manifest["split"]["test"]
        if manifest.get("complete") and all(
            (local / "sequences" / f"{n}.npz").is_file() for n in split
        ):
            return local
    except (OSError, ValueError, KeyError, TypeError):
        pass
    return request.getfixturevalue("dance_unpacked")
