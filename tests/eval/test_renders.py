"""The error sheet (loosefit.eval.renders): what it draws, with the renderer replaced by one
that records its scenes (no OpenGL needed)."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

import loosefit.render.renderer as renderer_module
from loosefit.eval.renders import error_sheet
from tests.meshes import cube, grid

SIZE = 48


class Recorder:
    """Stands in for :class:`~loosefit.render.renderer.Renderer`: keeps every scene, draws a
    grey picture of two views."""

    scenes: list = []

    def __init__(self, config):
        assert config.views == ("front", "side") and config.width == SIZE

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def render_sequence(self, scene):
        Recorder.scenes.append(scene)
        yield np.full((SIZE, 2 * SIZE, 3), 128, np.uint8)


@pytest.fixture
def recorded(monkeypatch):
    Recorder.scenes = []
    monkeypatch.setattr(renderer_module, "Renderer", Recorder)
    return Recorder.scenes


def test_each_method_coloured_by_its_distance_to_the_truth(recorded, tmp_path):
    import matplotlib

    T, frame, vmax = 3, 1, 4.0
    v, f = grid(4, -0.2, 0.2, 1.0)
    truth = np.repeat(v[None], T, axis=0)  # (T, 16, 3)
    rng = np.random.default_rng(0)
    ours = truth + rng.normal(0, 0.02, truth.shape).astype(np.float32)
    body_v, body_f = cube(0.3)
    body = np.repeat(body_v[None], T, axis=0)
    out = tmp_path / "sheet.jpg"
    error_sheet(
        out,
        frame,
        truth,
        {"ours": ours[frame]},
        body,
        body_f,
        faces=f,
        vmax=vmax,
        size=SIZE,
        where="c",
    )

    assert len(recorded) == 2  # the truth, then each method
    (body_mesh, truth_mesh), (_, ours_mesh) = recorded
    assert body_mesh.name == "body" and truth_mesh.vertex_colors is None
    np.testing.assert_array_equal(truth_mesh.vertices.reshape(-1, 3), truth[frame])
    cmap = matplotlib.colormaps["inferno"]
    expect, squared = [], 0.0
    for i in range(len(v)):  # vertex by vertex: the distance in cm, on the colour map
        d = 100 * float(np.linalg.norm(ours[frame, i] - truth[frame, i]))
        expect.append(cmap(min(d / vmax, 1.0))[:3])
        squared += d * d
    np.testing.assert_allclose(ours_mesh.vertex_colors.reshape(-1, 3), expect, atol=1e-6)
    rmse = np.sqrt(squared / len(v))
    assert ours_mesh.name == f"ours (RMSE {rmse:.1f} cm)"

    with Image.open(out) as image:  # two panels side by side, the colour bar below them
        width, height = image.size
    assert width >= 2 * 2 * SIZE and height > SIZE
