"""Write rendered frames to disk: H.264 MP4, numbered PNGs, and contact sheets.

Writers are atomic (:func:`~loosefit.atomic.atomic_path`): an MP4 is encoded into a
temporary file and renamed over ``<name>.mp4`` only once every frame is in, and each PNG
is written to a temporary name first, so an interrupted or failed run never leaves a
file that looks complete. On an exception the temporary file is deleted.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont
from tqdm.auto import tqdm

from loosefit.atomic import atomic_path
from loosefit.errors import LoosefitInputError


def _check_frame(frame: np.ndarray, index: int, size: tuple[int, int] | None) -> np.ndarray:
    """Return ``frame`` as a contiguous (H, W, 3) uint8 array of the expected size, or raise."""
    frame = np.asarray(frame)
    if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
        raise LoosefitInputError(
            "frames", f"frame {index}", "an (H, W, 3) uint8 image", f"{frame.shape} {frame.dtype}"
        )
    if size is not None and frame.shape[:2] != size:
        raise LoosefitInputError(
            "frames", f"frame {index}", f"size {size} like frame 0", f"size {frame.shape[:2]}"
        )
    return np.ascontiguousarray(frame)


def _pad_even(frame: np.ndarray) -> np.ndarray:
    """Pad the bottom / right edge by repetition to even height and width (yuv420p needs it)."""
    h, w = frame.shape[:2]
    if h % 2 == 0 and w % 2 == 0:
        return frame
    return np.pad(frame, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")


def _total(frames: Iterable, total: int | None) -> int | None:
    if total is not None:
        return total
    try:
        return len(frames)  # type: ignore[arg-type]
    except TypeError:
        return None


def write_video(
    frames: Iterable[np.ndarray],
    path: str | os.PathLike,
    fps: float,
    *,
    crf: int = 18,
    preset: str = "medium",
    total: int | None = None,
    progress: bool = True,
) -> Path:
    """Encode frames into an H.264 MP4 (yuv420p, ``+faststart``), atomically.

    Frames with odd height or width are padded by one edge row / column.

    Args:
        frames: (H, W, 3) uint8 images, all the same size; any iterable (e.g. a
            renderer's :meth:`~loosefit.render.renderer.Renderer.render_sequence`).
        path: output ``.mp4`` path; its folder is created.
        fps: frames per second.
        crf: x264 constant rate factor, 0 (lossless) to 51; 18 is visually lossless.
        preset: x264 speed / size trade-off ("ultrafast" ... "veryslow").
        total: number of frames, for the progress bar's ETA (default ``len(frames)`` if any).
        progress: show a tqdm progress bar.

    Returns:
        the path written.

    Raises:
        LoosefitInputError: on a bad argument, no frames, or a frame of the wrong shape.
    """
    import imageio_ffmpeg

    path = Path(path)
    if path.suffix.lower() != ".mp4":
        raise LoosefitInputError(path, "path", "a .mp4 file name", repr(path.suffix))
    if not (np.isfinite(fps) and fps > 0):
        raise LoosefitInputError(path, "fps", "a positive frame rate", repr(fps))
    if not 0 <= crf <= 51:
        raise LoosefitInputError(path, "crf", "an integer in [0, 51]", repr(crf))
    path.parent.mkdir(parents=True, exist_ok=True)
    writer = None
    count = 0
    bar = tqdm(total=_total(frames, total), disable=not progress, unit="frame", desc=path.name)
    try:
        with atomic_path(path) as partial:
            try:
                size = None
                for frame in frames:
                    frame = _check_frame(frame, count, size)
                    if writer is None:
                        size = frame.shape[:2]
                        h, w = _pad_even(frame).shape[:2]
                        writer = imageio_ffmpeg.write_frames(
                            str(partial),
                            (w, h),
                            fps=fps,
                            codec="libx264",
                            quality=None,  # rate control is by -crf below
                            pix_fmt_in="rgb24",
                            pix_fmt_out="yuv420p",
                            macro_block_size=1,  # we pad to even sizes ourselves; never rescale
                            output_params=[
                                "-crf",
                                str(int(crf)),
                                "-preset",
                                preset,
                                "-movflags",
                                "+faststart",
                            ],
                        )
                        writer.send(None)  # start ffmpeg
                    writer.send(_pad_even(frame))
                    count += 1
                    bar.update(1)
                if writer is None:
                    raise LoosefitInputError(path, "frames", "at least one frame", "none")
                writer.close()
                writer = None
            except BaseException:
                if writer is not None:
                    try:
                        writer.close()
                    except Exception:  # noqa: BLE001 - already failing; the original error matters
                        pass
                raise
    finally:
        bar.close()
    return path


def write_frames_png(
    frames: Iterable[np.ndarray],
    folder: str | os.PathLike,
    pattern: str = "frame_{:05d}.png",
    *,
    start: int = 0,
    total: int | None = None,
    progress: bool = True,
) -> list[Path]:
    """Write frames as numbered PNG files, each one atomically.

    Args:
        frames: (H, W, 3) uint8 images.
        folder: output folder; created if missing.
        pattern: file name with one ``str.format`` field for the frame number.
        start: number of the first frame.
        total: number of frames, for the progress bar (default ``len(frames)`` if any).
        progress: show a tqdm progress bar.

    Returns:
        the paths written, in order.
    """
    folder = Path(folder)
    if pattern.format(0) == pattern.format(1):
        raise LoosefitInputError(pattern, "pattern", "a format field for the frame number", pattern)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    with tqdm(
        total=_total(frames, total), disable=not progress, unit="frame", desc=str(folder)
    ) as bar:
        for i, frame in enumerate(frames):
            frame = _check_frame(frame, i, None)
            path = folder / pattern.format(start + i)
            with atomic_path(path) as tmp:
                Image.fromarray(frame).save(tmp, format="PNG")
            paths.append(path)
            bar.update(1)
    return paths


def contact_sheet(
    images: Sequence[np.ndarray],
    cols: int,
    *,
    labels: Sequence[str] | None = None,
    gap: int = 4,
    background: tuple[int, int, int] = (255, 255, 255),
    font_size: int = 16,
) -> np.ndarray:
    """Tile images into a grid, row by row (a clip at a glance).

    Images of different sizes are centred in cells of the largest size.

    Args:
        images: N (H_i, W_i, 3) uint8 images.
        cols: images per row.
        labels: optional N captions drawn in the top-right corner of each cell (the
            renderer's own title and view names sit top-left and bottom-left).
        gap: pixels between cells and around the sheet.
        background: colour of the gaps, 0-255 RGB.
        font_size: caption size, pixels.

    Returns:
        (rows * (H + gap) + gap, cols * (W + gap) + gap, 3) uint8 image, rows = ceil(N / cols).
    """
    if len(images) == 0:
        raise LoosefitInputError("contact_sheet", "images", "at least one image", "none")
    if cols < 1:
        raise LoosefitInputError("contact_sheet", "cols", ">= 1", str(cols))
    if labels is not None and len(labels) != len(images):
        raise LoosefitInputError(
            "contact_sheet", "labels", f"{len(images)} labels", str(len(labels))
        )
    images = [_check_frame(im, i, None) for i, im in enumerate(images)]
    H = max(im.shape[0] for im in images)
    W = max(im.shape[1] for im in images)
    cols = min(cols, len(images))
    rows = -(-len(images) // cols)
    sheet = np.empty((rows * (H + gap) + gap, cols * (W + gap) + gap, 3), np.uint8)
    sheet[:] = np.asarray(background, np.uint8)
    for i, im in enumerate(images):
        r, c = divmod(i, cols)
        y = gap + r * (H + gap) + (H - im.shape[0]) // 2
        x = gap + c * (W + gap) + (W - im.shape[1]) // 2
        sheet[y : y + im.shape[0], x : x + im.shape[1]] = im
    if labels is not None:
        pil = Image.fromarray(sheet)
        draw = ImageDraw.Draw(pil)
        font = ImageFont.load_default(size=font_size)
        for i, text in enumerate(labels):
            r, c = divmod(i, cols)
            xy = (gap + c * (W + gap) + W - 6, gap + r * (H + gap) + 4)  # top right
            draw.text(
                xy,
                text,
                fill=(20, 20, 20),
                font=font,
                anchor="ra",
                stroke_width=2,
                stroke_fill=(255, 255, 255),
            )
        sheet = np.asarray(pil).copy()
    return sheet


def comparison_sheet(
    columns: dict[str, np.ndarray],
    frames: Sequence[int],
    body: np.ndarray,
    body_faces: np.ndarray,
    garment_faces: np.ndarray,
    config,
) -> np.ndarray:
    """Garments side by side on their body: one row a frame, one column a garment.

    Args:
        columns: label -> (K, V, 3) garment positions of the K frames shown.
        frames: the K frame numbers, for the labels.
        body: (K, Vb, 3) the posed body of those frames; body_faces: (Fb, 3).
        garment_faces: (F, 3) the garments' triangles.
        config: a :class:`~loosefit.render.renderer.RenderConfig` (views, size).

    Returns:
        (H, W, 3) uint8: the tiles with their labels ("LABEL, frame N").
    """
    from loosefit.render.renderer import Renderer, RenderMesh

    tiles = {}
    with Renderer(config) as renderer:
        for label, garment in columns.items():
            scene = [
                RenderMesh(body_faces, body, "body", name="body"),
                RenderMesh(garment_faces, garment, "garment", name=label),
            ]
            tiles[label] = list(renderer.render_sequence(scene))
    images, labels = [], []
    for i, frame in enumerate(frames):
        for label in columns:
            images.append(tiles[label][i])
            labels.append(f"{label}, frame {frame}")
    return contact_sheet(images, cols=len(columns), labels=labels)
