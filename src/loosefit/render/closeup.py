"""Close-ups of one frame: a camera aimed at a point, and the picture of cloth inside the body.

:func:`render_penetration` draws one frame three times side by side: the whole figure,
a close-up of a point (where the cloth is deepest inside the body), and the same
close-up with the body parts the cloth is inside (and those it passes through) left out,
so the buried cloth shows; the close-ups look from where most of it is in sight.
The cloth's vertices given as ``deep`` are red on a pale blue garment; body parts the
cloth does not collide with (``muted``) are sand-coloured.
"""

from __future__ import annotations

import math

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from loosefit.errors import LoosefitInputError
from loosefit.render.camera import look_at, perspective
from loosefit.render.renderer import RenderConfig, Renderer, RenderMesh

GARMENT = (0.62, 0.71, 0.84)  # sRGB of the cloth
DEEP = (0.92, 0.06, 0.04)  # sRGB of the cloth deeper inside the body than the tolerance
BODY = (0.72, 0.72, 0.74)  # sRGB of skin the cloth collides with
MUTED = (0.86, 0.78, 0.56)  # sRGB of body parts the cloth does not collide with


def closeup_camera(
    target: np.ndarray, direction: np.ndarray, radius: float, fov_y_deg: float = 30.0
) -> tuple[np.ndarray, np.ndarray]:
    """A square camera looking at ``target`` (3,) from ``direction`` (3,), framing a sphere
    of ``radius`` metres: (view (4, 4), proj (4, 4)) for :meth:`Renderer.render_frame`."""
    d = np.asarray(direction, np.float64)
    if not np.isfinite(d).all() or np.linalg.norm(d) < 1e-9 or radius <= 0:
        raise LoosefitInputError(
            "closeup_camera",
            "direction, radius",
            "a non-zero direction and radius > 0",
            f"{d}, {radius}",
        )
    d /= np.linalg.norm(d)
    distance = radius / math.sin(math.radians(fov_y_deg) / 2)
    eye = np.asarray(target, np.float64) + distance * d
    up = (0.0, 0.0, 1.0) if abs(d[2]) < 0.99 else (0.0, 1.0, 0.0)
    near = max(0.01, distance - 4 * radius)
    return look_at(eye, target, up), perspective(fov_y_deg, 1.0, near, distance + 4 * radius)


def _red_pixels(image: np.ndarray) -> int:
    """How many pixels of an (H, W, 3) uint8 image show the :data:`DEEP` cloth (shaded)."""
    r, g, b = (image[..., i].astype(np.int32) for i in range(3))
    return int(((r > 60) & (r > 2 * g) & (r > 2 * b)).sum())


def clearest_direction(
    renderer: Renderer,
    scene: list[RenderMesh],
    target: np.ndarray,
    radius: float,
    preferred: np.ndarray,
) -> np.ndarray:
    """(3,) the direction, among ``preferred`` and 16 around ``target`` (every 45 degrees
    of azimuth at 10 and 45 degrees of elevation), from which the close-up of ``scene``
    shows the most :data:`DEEP` cloth; ``preferred`` wins ties."""
    candidates = [np.asarray(preferred, np.float64)]
    for elevation in (10.0, 45.0):
        for azimuth in range(0, 360, 45):
            a, e = np.radians(azimuth), np.radians(elevation)
            candidates.append(np.array([np.sin(a) * np.cos(e), -np.cos(a) * np.cos(e), np.sin(e)]))
    seen = [
        _red_pixels(renderer.render_frame(scene, camera=closeup_camera(target, d, radius)))
        for d in candidates
    ]
    return candidates[int(np.argmax(seen))]


def _colors(n: int, base, marked: np.ndarray | None, mark) -> np.ndarray:
    c = np.tile(np.asarray(base, np.float32), (n, 1))  # (n, 3)
    if marked is not None:
        c[np.asarray(marked, bool)] = mark
    return c


def render_penetration(
    body_vertices: np.ndarray,
    body_faces: np.ndarray,
    garment_vertices: np.ndarray,
    garment_faces: np.ndarray,
    deep: np.ndarray,
    target: np.ndarray,
    *,
    direction: np.ndarray,
    hidden: np.ndarray | None = None,
    muted: np.ndarray | None = None,
    radius: float = 0.3,
    size: int = 400,
    search: bool = True,
    title: str = "",
    hidden_label: str = "",
    renderer: Renderer | None = None,
) -> np.ndarray:
    """Three views of one frame: the whole figure, a close-up, and the close-up with the
    ``hidden`` and ``muted`` body parts left out.

    Args:
        body_vertices: (Vb, 3) the posed body.
        body_faces: (Fb, 3) its triangles (the whole body, not only the collider).
        garment_vertices: (V, 3) the garment.
        garment_faces: (F, 3) its triangles.
        deep: (V,) bool, the cloth drawn red.
        target: (3,) the point the close-ups look at.
        direction: (3,) from ``target`` towards the cameras (with ``search``, the one
            preferred among those :func:`clearest_direction` tries).
        hidden: (Vb,) bool, body vertices whose faces the third view leaves out.
        muted: (Vb,) bool, body vertices drawn sand-coloured (parts the cloth passes
            through), also left out of the third view.
        radius: m, the sphere around ``target`` the close-ups frame.
        size: pixels of each (square) view.
        search: look from the direction that shows the most red cloth in the third view.
        title: drawn at the top left.
        hidden_label: what the third view leaves out, for its label.
        renderer: one to reuse (its views are ``size`` square, no labels); default: a new one.

    Returns:
        (size, 3 size, 3) uint8 image.
    """
    body = np.asarray(body_vertices, np.float32)
    garment = np.asarray(garment_vertices, np.float32)
    body_faces = np.asarray(body_faces, np.int64)
    body_colors = _colors(len(body), BODY, muted, MUTED)
    cloth = RenderMesh(
        garment_faces,
        garment,
        "garment",
        name="garment",
        vertex_colors=_colors(len(garment), GARMENT, deep, DEEP),
    )
    whole = [RenderMesh(body_faces, body, "body", name="body", vertex_colors=body_colors), cloth]
    cut = body_faces
    gone = np.zeros(len(body), bool)
    for mask in (hidden, muted):
        if mask is not None:
            gone |= np.asarray(mask, bool)
    cut = body_faces[~gone[body_faces].any(axis=1)]
    opened = [cloth]
    if len(cut):
        opened.insert(0, RenderMesh(cut, body, "body", name="body", vertex_colors=body_colors))
    own = renderer is None
    if own:
        renderer = Renderer(
            RenderConfig(width=size, height=size, labels=False, frame_counter=False)
        )
    try:
        if search:
            direction = clearest_direction(renderer, opened, target, radius, direction)
        lo, hi = body.min(0), body.max(0)
        flat = np.asarray(direction, np.float64) * [1.0, 1.0, 0.0]
        side = flat if np.linalg.norm(flat) > 1e-6 else np.array([0.0, -1.0, 0.0])
        side = side / np.linalg.norm(side) + [0.0, 0.0, 0.25]
        cameras = [
            closeup_camera((lo + hi) / 2, side, 0.55 * float(np.linalg.norm(hi - lo))),
            closeup_camera(target, direction, radius),
            closeup_camera(target, direction, radius),
        ]
        images = [
            renderer.render_frame(scene, camera=cam)
            for scene, cam in zip((whole, whole, opened), cameras, strict=True)
        ]
    finally:
        if own:
            renderer.close()
    gone = [hidden_label or "the parts it is in"]
    if muted is not None and np.any(muted):
        gone.append("sand parts")
    labels = ["whole body", "close-up", "hidden: " + ", ".join(gone)]
    view, proj = cameras[0]
    clip = proj.astype(np.float64) @ view @ np.append(np.asarray(target, np.float64), 1.0)
    height, width = images[0].shape[:2]
    mark = ((clip[0] / clip[3] + 1) / 2 * width, (1 - clip[1] / clip[3]) / 2 * height)
    return _label(np.concatenate(images, axis=1), labels, title, width, mark)


def _label(
    image: np.ndarray, labels: list[str], title: str, width: int, mark: tuple[float, float]
) -> np.ndarray:
    """Labels under each view, the title, and a red ring at ``mark`` (x, y) pixels."""
    pil = Image.fromarray(image)
    draw = ImageDraw.Draw(pil)
    font = ImageFont.load_default(size=max(11, width // 28))
    pad = max(4, width // 60)
    r = width / 16
    draw.ellipse(
        (mark[0] - r, mark[1] - r, mark[0] + r, mark[1] + r),
        outline=tuple(int(255 * c) for c in DEEP),
        width=max(2, width // 150),
    )
    for i, text in enumerate(labels):
        draw.text(
            (i * width + pad, image.shape[0] - pad), text, fill=(40, 40, 45), font=font, anchor="ld"
        )
    if title:
        draw.text((pad, pad), title, fill=(40, 40, 45), font=font, anchor="la")
    return np.asarray(pil)
