"""Every export opened in real Blender (``bpy``, Blender as a Python module) as a user
opens it, with the importers' defaults (a PC2: the OBJ beside it imported, a Mesh Cache
modifier reading the cache): its vertices at three frames, in Blender's world, match
loosefit's to 0.01 mm in the right axes and units, and the garment's UVs arrive on the
right corners.

Blender runs in a subprocess (:mod:`loosefit.export.blender_read`): its own USD libraries
must not meet usd-core's in one process. Skipped, with the reason, where ``bpy`` is not
installed (``scripts/install.sh`` installs it).
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import loosefit.export
from loosefit.export import ExportConfig, export_animation
from loosefit.export.gltf import split_uvs
from tests.export.rigged import dressed

pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("bpy") is None,
    reason="Blender as a Python module is not installed (pip install --no-deps bpy==5.0.1)",
)
READER = Path(loosefit.export.__file__).with_name("blender_read.py")
FRAMES = [0, 2, 4]
FPS = 24.0
# Blender's Alembic and OBJ importers turn Y up to Z up: (x, y, z) -> (x, -z, y).
YUP_IN_BLENDER = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def _open_in_blender(path: Path) -> dict:
    out = path.with_suffix(".seen.npz")
    cmd = [sys.executable, str(READER), str(path), "--fps", str(FPS), "--out", str(out)]
    run = subprocess.run(cmd + ["--frames", *map(str, FRAMES)], capture_output=True, text=True)
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    return dict(np.load(out))


CASES = {
    "abc": ("a.abc", None, np.eye(3)),
    "abc-zup": ("z.abc", ExportConfig(up_axis="Z"), YUP_IN_BLENDER),  # read as if Y up
    "usd-skinned": ("s.usdc", None, np.eye(3)),
    "usd-points": ("p.usdc", ExportConfig(skinned_body=False), np.eye(3)),
    "glb": ("g.glb", None, np.eye(3)),
    "pc2": ("c.pc2", None, np.eye(3)),
    "pc2-zup": ("zc.pc2", ExportConfig(up_axis="Z"), YUP_IN_BLENDER),  # read as if Y up
}


@pytest.mark.parametrize("case", list(CASES))
def test_blender_sees_the_exported_vertices_at_three_frames(tmp_path, monkeypatch, case):
    import loosefit.export.usd

    monkeypatch.setattr(loosefit.export.usd, "SAVE_EVERY", 2)  # saved in pieces, as a long one
    name, config, axes = CASES[case]
    meshes = dressed(T=5)
    export_animation(tmp_path / name, meshes, FPS, config)
    seen = _open_in_blender(tmp_path / name)
    for m in meshes:
        source = split_uvs(m)[0] if name.endswith(".glb") else np.arange(m.vertices.shape[1])
        want = m.vertices[FRAMES][:, source].astype(np.float64) @ axes.T
        assert seen[m.name].shape == want.shape, m.name
        err = np.linalg.norm(seen[m.name] - want, axis=-1).max()
        assert err < 1e-5, f"{m.name}: {err * 1e3:.4f} mm"  # 0.01 mm
    g = meshes[0]
    if name.endswith(".pc2"):  # the OBJ's vertices and faces in loosefit's order
        np.testing.assert_array_equal(seen["garment.faces"], g.faces)
    # the garment's UVs: at each Blender face corner, the UV loosefit gave that corner
    source = split_uvs(g)[0] if name.endswith(".glb") else np.arange(g.vertices.shape[1])
    corner_uv = {
        (frozenset(f), v): g.uvs[u]
        for f, fu in zip(g.faces, g.face_uvs, strict=True)
        for v, u in zip(f, fu, strict=True)
    }
    faces, uv = seen["garment.faces"], seen["garment.uv"].reshape(-1, 3, 2)
    for f, uvs in zip(source[faces], uv, strict=True):
        for v, got in zip(f, uvs, strict=True):
            np.testing.assert_allclose(got, corner_uv[(frozenset(f.tolist()), v)], atol=1e-6)
