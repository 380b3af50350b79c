"""Render a whole animated scene to an MP4, chosen PNG frames and a contact sheet, in one pass;
or one frame of it to a PNG (:func:`render_still`)."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

from loosefit.atomic import atomic_path
from loosefit.render.renderer import RenderConfig, Renderer, RenderMesh
from loosefit.render.video import contact_sheet, write_video


@dataclass
class ClipOutputs:
    """Files written by :func:`render_clip`.

    Attributes:
        video: the MP4.
        frames: PNG files of the frames kept (every ``png_every``-th).
        sheet: a contact sheet PNG of evenly spaced frames, or None.
    """

    video: Path
    frames: list[Path]
    sheet: Path | None


def render_clip(
    scene: Sequence[RenderMesh],
    out_dir: str | Path,
    fps: float,
    config: RenderConfig | None = None,
    title: str | None = None,
    png_every: int = 0,
    *,
    sheet_frames: int = 8,
    name: str = "video",
) -> ClipOutputs:
    """Render every frame once and write ``<name>.mp4``, PNGs and ``<name>_sheet.png``.

    Args:
        scene: meshes with T frames each (or static).
        out_dir: output folder (created).
        fps: frame rate of the video.
        config: how it looks (views, size, ...).
        title: drawn on each frame.
        png_every: also save every Nth frame as ``frames/frame_XXXXX.png`` (0: none).
        sheet_frames: frames on the contact sheet (0: no sheet).
        name: base name of the video and sheet.

    Returns:
        The written files. The video is written atomically: a failed render
        leaves no MP4 behind.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    pngs: list[Path] = []
    sheet_images: list[np.ndarray] = []
    with Renderer(config) as renderer:
        frames = renderer.render_sequence(scene, title=title, fps=fps)
        T = len(frames)
        picks = set(np.linspace(0, T - 1, min(sheet_frames, T)).round().astype(int).tolist())
        if png_every > 0:
            (out_dir / "frames").mkdir(exist_ok=True)

        def tap() -> Iterator[np.ndarray]:
            for t, image in enumerate(frames):
                if png_every > 0 and t % png_every == 0:
                    path = out_dir / "frames" / f"frame_{t:05d}.png"
                    Image.fromarray(image).save(path)
                    pngs.append(path)
                if sheet_frames > 0 and t in picks:
                    sheet_images.append(image)
                yield image

        video = write_video(tap(), out_dir / f"{name}.mp4", fps=fps, total=T)
    sheet = None
    if sheet_images:
        cols = 2 if sheet_images[0].shape[1] > sheet_images[0].shape[0] * 1.5 else 4
        sheet = out_dir / f"{name}_sheet.png"
        Image.fromarray(contact_sheet(sheet_images, cols=cols)).save(sheet)
    return ClipOutputs(video=Path(video), frames=pngs, sheet=sheet)


def render_still(
    scene: Sequence[RenderMesh],
    path: str | Path,
    config: RenderConfig | None = None,
    title: str | None = None,
    frame: int = 0,
) -> np.ndarray:
    """Render one frame of a scene from every view of ``config``, tiled side by side, and
    write it as a PNG (atomically: a failed render leaves no file behind).

    Args:
        scene: meshes with T frames each (or static).
        path: the PNG to write (its folder must exist).
        config: how it looks (views, size, ...).
        title: drawn top-left.
        frame: which frame.

    Returns:
        The (H, N * W, 3) uint8 image written, N views.
    """
    config = config or RenderConfig(frame_counter=False)
    with Renderer(config) as renderer:
        image = next(iter(renderer.render_sequence(scene, title=title, frames=[frame])))
    with atomic_path(Path(path)) as tmp:
        Image.fromarray(image).save(tmp, format="PNG")
    return image
