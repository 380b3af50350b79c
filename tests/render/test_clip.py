import gc

import imageio.v2 as imageio
import numpy as np
import pytest
from PIL import Image

from loosefit.render.clip import render_clip, render_still
from loosefit.render.geometry import uv_sphere
from loosefit.render.renderer import RenderConfig, RenderMesh

SIZE = 48
T = 5


def _scene():
    """A ball rising 10 cm a frame over T frames."""
    v, f = uv_sphere(0.3, 16, 8, center=(0.0, 0.0, 1.0))
    frames = v[None] + np.array([0.0, 0.0, 0.1], np.float32) * np.arange(T)[:, None, None]
    return [RenderMesh(f, frames, "other", name="ball")]


def _config(**overrides):
    return RenderConfig(width=SIZE, height=SIZE, labels=False, frame_counter=False, **overrides)


def _or_skip(run):
    try:
        return run()
    except RuntimeError as exc:
        pytest.skip(f"no headless OpenGL (EGL) context on this machine: {exc}")


@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")  # imageio's reader
def test_a_clip_writes_its_video_every_second_frame_and_a_sheet(tmp_path):
    out = _or_skip(
        lambda: render_clip(
            _scene(), tmp_path / "out", fps=10, config=_config(), png_every=2, sheet_frames=3
        )
    )
    assert out.video == tmp_path / "out" / "video.mp4"
    assert [p.name for p in out.frames] == ["frame_00000.png", "frame_00002.png", "frame_00004.png"]
    with imageio.get_reader(out.video) as reader:
        video = [np.asarray(frame) for frame in reader]
    gc.collect()
    assert len(video) == T and video[0].shape == (SIZE, SIZE, 3)
    pngs = [np.asarray(Image.open(p)) for p in out.frames]
    for t, png in zip((0, 2, 4), pngs, strict=True):  # the video is the PNGs, lossy
        assert np.abs(video[t].astype(int) - png).mean() < 4
    assert not np.array_equal(pngs[0], pngs[2])  # the ball moved
    sheet = np.asarray(Image.open(out.sheet))
    assert out.sheet.name == "video_sheet.png"
    assert sheet.shape == (SIZE + 8, 3 * SIZE + 16, 3)  # three square frames in one row
    np.testing.assert_array_equal(sheet[4 : 4 + SIZE, 4 : 4 + SIZE], pngs[0])
    np.testing.assert_array_equal(sheet[4 : 4 + SIZE, -4 - SIZE : -4], pngs[2])


def test_no_sheet_and_no_pngs_unless_asked(tmp_path):
    out = _or_skip(
        lambda: render_clip(_scene(), tmp_path, fps=10, config=_config(), sheet_frames=0, name="x")
    )
    assert out.sheet is None and out.frames == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.mp4"]


def test_a_still_is_one_frame_of_every_view_side_by_side(tmp_path):
    path = tmp_path / "still.png"
    config = _config(views=("front", "side"))
    image = _or_skip(lambda: render_still(_scene(), path, config, frame=3))
    assert image.shape == (SIZE, 2 * SIZE, 3)
    np.testing.assert_array_equal(np.asarray(Image.open(path)), image)
    first = render_still(_scene(), tmp_path / "first.png", config, frame=0)
    assert not np.array_equal(first, image)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["first.png", "still.png"]
