"""Alembic point caches read back with the bindings themselves: positions on every frame in
the axes asked for, triangles reversed (Alembic winds clockwise), the frame rate; and the
message when the bindings are missing."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.export.alembic import export_alembic
from loosefit.export.meshes import AnimatedMesh, ExportConfig
from tests.meshes import grid


def _garment(T: int = 3) -> AnimatedMesh:
    v, f = grid(3, -0.2, 0.2, 1.0)
    moves = v[None] + np.arange(T, dtype=np.float32)[:, None, None] * np.float32(
        [0.01, -0.02, 0.03]
    )
    return AnimatedMesh("garment", f, moves)


@pytest.mark.parametrize("up", ["Z", "Y"])
def test_positions_and_reversed_triangles_read_back(tmp_path, up):
    pytest.importorskip("alembic3d", reason="the Alembic bindings: pip install 'loosefit[alembic]'")
    from alembic3d import Abc, AbcGeom

    m = _garment()
    path = tmp_path / "g.abc"
    assert export_alembic(path, [m], 30.0, ExportConfig(up_axis=up)) == [path]
    (child,) = Abc.IArchive(str(path)).getTop().children
    assert child.getName() == "garment"
    schema = AbcGeom.IPolyMesh(child, Abc.WrapExistingFlag.kWrapExisting).getSchema()
    assert schema.getNumSamples() == 3
    assert schema.getTimeSampling().getTimeSamplingType().getTimePerCycle() == pytest.approx(1 / 30)
    # Y up: (x, y, z) written as (x, z, -y)
    written = (
        m.vertices
        if up == "Z"
        else np.stack([m.vertices[..., 0], m.vertices[..., 2], -m.vertices[..., 1]], -1)
    )
    for t in range(3):
        sample = schema.getValue(Abc.ISampleSelector(t / 30.0))
        np.testing.assert_allclose(
            np.asarray(memoryview(sample.getPositions())), written[t], atol=1e-7
        )
    faces = np.asarray(memoryview(sample.getFaceIndices())).reshape(-1, 3)
    np.testing.assert_array_equal(faces, m.faces[:, ::-1])
    assert set(np.asarray(memoryview(sample.getFaceCounts())).tolist()) == {3}


def test_without_the_bindings_the_error_says_how_to_install_them(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "alembic3d", None)  # import alembic3d fails
    with pytest.raises(LoosefitInputError, match=r"pip install 'loosefit\[alembic\]'"):
        export_alembic(tmp_path / "g.abc", [_garment()], 30.0)
    assert not (tmp_path / "g.abc").exists()
