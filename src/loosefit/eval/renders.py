"""Pictures of garments against a reference, coloured by their distance to it.

:func:`error_sheet`: the reference and each method at one frame, front and side, every
garment vertex coloured by its distance to the reference's, with a colour bar.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def error_sheet(
    out_path: Path,
    frame: int,
    truth,
    garments: dict,
    body,
    body_faces,
    *,
    faces,
    vmax: float,
    size: int,
    where: str = "chain",
    truth_label: str = "simulation",
) -> None:
    """Simulation | methods at one frame, front and side, coloured by error, with a colour bar.

    Args:
        out_path: the picture to write (JPEG, quality 88, or any format PIL names by suffix).
        frame: the frame shown.
        truth: (T, V, 3) the reference garment (the simulation).
        garments: label -> (V, 3) each method's garment at ``frame``, coloured by its
            per-vertex distance to ``truth[frame]`` (cm, ``vmax`` at the top of the colour map).
        body: (T, Vb, 3) the posed body; body_faces: (Fb, 3) its triangles.
        faces: (F, 3) the garment's triangles.
        vmax: cm, the colour bar's top.
        size: pixels, each view's width and height.
        where: the clip's name in the colour bar's label; truth_label: the reference's.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from PIL import Image

    from loosefit.render.renderer import RenderConfig, Renderer, RenderMesh
    from loosefit.render.video import contact_sheet

    cmap = plt.get_cmap("inferno")
    config = RenderConfig(
        width=size, height=size, views=("front", "side"), follow=True, frame_counter=False
    )
    images, labels = [], []
    with Renderer(config) as renderer:
        for label, g in {truth_label: truth[frame], **garments}.items():
            colours = None
            if label != truth_label:
                err = 100 * np.linalg.norm(g - truth[frame], axis=-1)  # (V,) cm
                colours = cmap(np.clip(err / vmax, 0, 1))[:, :3]
                label = f"{label} (RMSE {np.sqrt((err**2).mean()):.1f} cm)"
            scene = [
                RenderMesh(body_faces, body[frame], "body", name="body"),
                RenderMesh(faces, g, "garment", vertex_colors=colours, name=label),
            ]
            images.append(next(iter(renderer.render_sequence(scene))))
            labels.append(label)
    sheet = contact_sheet(images, cols=2, labels=labels)
    fig, ax = plt.subplots(figsize=(sheet.shape[1] / 100, 0.8), dpi=100)
    mappable = matplotlib.cm.ScalarMappable(matplotlib.colors.Normalize(0, vmax), cmap)
    text = f"per-vertex distance to the {truth_label} (cm), {where} frame {frame}"
    fig.colorbar(mappable, cax=ax, orientation="horizontal", label=text)
    fig.subplots_adjust(left=0.05, right=0.95, bottom=0.55, top=0.9)
    fig.canvas.draw()
    bar = np.asarray(fig.canvas.buffer_rgba())[..., :3]
    plt.close(fig)
    w = max(sheet.shape[1], bar.shape[1])
    pad = lambda im: np.pad(im, ((0, 0), (0, w - im.shape[1]), (0, 0)), constant_values=255)  # noqa: E731
    Image.fromarray(np.concatenate([pad(sheet), pad(bar)])).save(out_path, quality=88)
