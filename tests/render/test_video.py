"""Tests for render/video.py: MP4 and PNG writers, contact sheets."""

from __future__ import annotations

import gc

import imageio.v2 as imageio
import numpy as np
import pytest
from PIL import Image

from loosefit.errors import LoosefitInputError
from loosefit.render.video import contact_sheet, write_frames_png, write_video


def _frames(n: int, h: int = 48, w: int = 64) -> list[np.ndarray]:
    """Frames with a white square walking left to right on a dark background."""
    out = []
    for i in range(n):
        f = np.full((h, w, 3), 30, np.uint8)
        x = 4 + i * (w - 16) // max(n - 1, 1)
        f[h // 2 - 6 : h // 2 + 6, x : x + 12] = 255
        out.append(f)
    return out


def _read(path) -> list[np.ndarray]:
    with imageio.get_reader(path) as reader:
        frames = [np.asarray(f) for f in reader]
    gc.collect()  # imageio's ffmpeg reader leaves pipes to the GC: keep its warnings in this test
    return frames


# imageio's ffmpeg *reader* leaks its pipe file objects (ResourceWarning); not ours to fix.
reader_leaks = pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")


@reader_leaks
def test_write_video_round_trip(tmp_path):
    path = write_video(iter(_frames(10)), tmp_path / "clip.mp4", fps=12, progress=False)
    assert path == tmp_path / "clip.mp4"
    back = _read(path)
    assert len(back) == 10
    assert back[0].shape == (48, 64, 3)
    assert not list(tmp_path.glob("*partial*"))  # the temporary file, whatever its name
    # The content moves: the bright square is further right in the last frame.
    xs = [np.nonzero(f[..., 0] > 128)[1].mean() for f in (back[0], back[-1])]
    assert xs[0] + 20 < xs[1]


@reader_leaks
def test_write_video_pads_odd_sizes(tmp_path):
    path = write_video(_frames(3, h=47, w=63), tmp_path / "odd.mp4", fps=10, progress=False)
    back = _read(path)
    assert len(back) == 3 and back[0].shape == (48, 64, 3)


def test_failing_frames_leave_no_video(tmp_path):
    def frames():
        yield from _frames(4)
        raise RuntimeError("renderer died")

    with pytest.raises(RuntimeError, match="renderer died"):
        write_video(frames(), tmp_path / "clip.mp4", fps=10, progress=False)
    assert list(tmp_path.iterdir()) == []


def test_bad_frames_are_rejected_without_leaving_a_file(tmp_path):
    frames = _frames(3)
    frames[2] = frames[2][:-2]  # a different size
    with pytest.raises(LoosefitInputError, match="frame 2"):
        write_video(frames, tmp_path / "clip.mp4", fps=10, progress=False)
    with pytest.raises(LoosefitInputError, match="at least one frame"):
        write_video([], tmp_path / "clip.mp4", fps=10, progress=False)
    with pytest.raises(LoosefitInputError, match="uint8"):
        write_video([np.zeros((8, 8, 3))], tmp_path / "clip.mp4", fps=10, progress=False)
    with pytest.raises(LoosefitInputError, match=".mp4"):
        write_video(_frames(1), tmp_path / "clip.avi", fps=10, progress=False)
    assert list(tmp_path.iterdir()) == []


def test_write_frames_png(tmp_path):
    frames = _frames(3)
    paths = write_frames_png(frames, tmp_path / "pngs", progress=False)
    assert [p.name for p in paths] == ["frame_00000.png", "frame_00001.png", "frame_00002.png"]
    for p, f in zip(paths, frames, strict=True):
        np.testing.assert_array_equal(np.asarray(Image.open(p)), f)
    assert sorted(p.name for p in (tmp_path / "pngs").iterdir()) == [p.name for p in paths]


def test_contact_sheet_layout():
    frames = _frames(5)
    sheet = contact_sheet(frames, cols=3, gap=2, labels=[str(i) for i in range(5)])
    assert sheet.shape == (2 * (48 + 2) + 2, 3 * (64 + 2) + 2, 3)
    np.testing.assert_array_equal(sheet[2 + 30 : 2 + 48, 2 : 2 + 64], frames[0][30:])
    empty_cell = sheet[2 + 50 + 10, 2 + 2 * 66 + 10]
    np.testing.assert_array_equal(empty_cell, [255, 255, 255])
    with pytest.raises(LoosefitInputError):
        contact_sheet([], cols=2)
