import math

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.render.closeup import (
    DEEP,
    clearest_direction,
    closeup_camera,
    render_penetration,
)
from loosefit.render.geometry import uv_sphere
from loosefit.render.renderer import RenderConfig, Renderer, RenderMesh

SIZE = 64


def _ndc(camera, points):
    view, proj = (m.astype(np.float64) for m in camera)
    h = np.c_[points, np.ones(len(points))] @ (proj @ view).T
    return h[:, :3] / h[:, 3:]


@pytest.mark.parametrize("direction", [(0.0, -1.0, 0.2), (0.0, 0.0, 1.0), (1.0, 1.0, -0.5)])
def test_the_closeup_camera_centres_its_target_and_frames_the_sphere(direction):
    target, radius = np.array([0.2, -0.1, 1.1]), 0.3
    camera = closeup_camera(target, np.array(direction), radius, fov_y_deg=30.0)
    np.testing.assert_allclose(_ndc(camera, target[None])[0, :2], 0.0, atol=1e-5)
    # the sphere touches the view's cone: a point of it square to the view at ndc cos(fov / 2)
    view = camera[0].astype(np.float64)
    side = np.linalg.inv(view)[:3, :3] @ [0.0, 1.0, 0.0]  # the image's up, in the world
    edge = _ndc(camera, (target + radius * side)[None])[0]
    assert edge[1] == pytest.approx(math.cos(math.radians(15.0)), abs=1e-4)
    assert -1 < edge[2] < 1  # within the near and far planes


def test_the_closeup_camera_refuses_no_direction_or_no_radius():
    with pytest.raises(LoosefitInputError, match="a non-zero direction and radius > 0"):
        closeup_camera(np.zeros(3), np.zeros(3), 0.3)
    with pytest.raises(LoosefitInputError, match="direction, radius"):
        closeup_camera(np.zeros(3), np.array([0.0, 1.0, 0.0]), -1.0)


def _renderer():
    try:
        return Renderer(RenderConfig(width=SIZE, height=SIZE, labels=False, frame_counter=False))
    except RuntimeError as exc:
        pytest.skip(f"no headless OpenGL (EGL) context on this machine: {exc}")


def _red(image):
    r, g, b = (image[..., i].astype(int) for i in range(3))
    return int(((r > 60) & (r > 2 * g) & (r > 2 * b)).sum())


def test_the_clearest_direction_looks_past_a_wall():
    """A red ball behind a wall on its front (-Y) side: the view from behind sees it."""
    v, f = uv_sphere(0.05, 12, 6, center=(0.0, 0.0, 1.0))
    ball = RenderMesh(f, v, "garment", vertex_colors=np.tile(DEEP, (len(v), 1)), name="ball")
    wall_v = np.array([[-1, -0.2, 0], [1, -0.2, 0], [1, -0.2, 2], [-1, -0.2, 2]], np.float32)
    wall = RenderMesh(np.array([[0, 1, 2], [0, 2, 3]]), wall_v, "other", name="wall")
    preferred = np.array([0.0, -1.0, 0.0])
    target, scene = np.array([0.0, 0.0, 1.0]), [wall, ball]
    with _renderer() as renderer:
        best = clearest_direction(renderer, scene, target, 0.2, preferred)
        seen = [
            _red(renderer.render_frame(scene, camera=closeup_camera(target, d, 0.2)))
            for d in (preferred, best)
        ]
    assert best[1] > -0.1  # not from the wall's side
    assert seen[0] == 0 and seen[1] > 50


def test_render_penetration_shows_the_buried_cloth_in_its_third_view():
    body_v, body_f = uv_sphere(0.3, 16, 8, center=(0.0, 0.0, 1.0))
    cloth_v, cloth_f = uv_sphere(0.12, 12, 6, center=(0.0, 0.0, 1.0))  # wholly inside
    deep = np.ones(len(cloth_v), bool)
    image = render_penetration(
        body_v,
        body_f,
        cloth_v,
        cloth_f,
        deep,
        target=np.array([0.0, 0.0, 1.0]),
        direction=np.array([0.0, -1.0, 0.0]),
        hidden=np.ones(len(body_v), bool),  # the whole body left out of the third view
        radius=0.3,
        size=SIZE,
        search=False,
    )
    assert image.shape == (SIZE, 3 * SIZE, 3) and image.dtype == np.uint8
    whole, closeup, opened = (image[:, i * SIZE : (i + 1) * SIZE] for i in range(3))
    # the ring drawn round the target is red too: only the third view has a red patch
    assert _red(opened[10:-16]) > 10 * max(1, _red(closeup[10:-16]))
