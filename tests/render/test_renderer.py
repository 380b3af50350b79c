"""Tests for render/camera.py, render/geometry.py and render/renderer.py (headless, CPU)."""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.render.camera import (
    VIEW_NAMES,
    camera_track,
    frame_views,
    look_at,
    named_view,
    perspective,
    smooth_track,
)
from loosefit.render.geometry import capsule, open_cone, smooth_vertex_normals, uv_sphere
from loosefit.render.renderer import RenderConfig, Renderer, RenderMesh

SIZE = 96  # small images keep the suite fast
RED = (0.9, 0.1, 0.1)


def _renderer(**overrides) -> Renderer:
    """A small renderer, or skip the test where no OpenGL context can be made."""
    settings = dict(width=SIZE, height=SIZE, labels=False, frame_counter=False) | overrides
    config = RenderConfig(**settings)
    try:
        return Renderer(config)
    except RuntimeError as exc:
        pytest.skip(f"no headless OpenGL (EGL) context on this machine: {exc}")


@pytest.fixture(scope="module")
def renderer():
    r = _renderer()
    yield r
    r.close()


def _sphere(center=(0.0, 0.0, 1.0), radius=0.5, frames=None, **kwargs) -> RenderMesh:
    v, f = uv_sphere(radius, 32, 16, center=center)
    if frames is not None:
        v = v[None] + np.asarray(frames, np.float32)[:, None]  # (T, V, 3) translated copies
    return RenderMesh(f, v, role="other", color=RED, **kwargs)


def _is_background(pixel: np.ndarray, config: RenderConfig) -> bool:
    return bool(np.abs(pixel.astype(float) - np.asarray(config.background) * 255).max() <= 2)


# -- geometry ---------------------------------------------------------------------------------


def _naive_normals(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    out = np.zeros_like(v, dtype=np.float64)
    for a, b, c in f:
        n = np.cross(v[b] - v[a], v[c] - v[a])
        out[a] += n
        out[b] += n
        out[c] += n
    for i in range(len(out)):
        length = np.linalg.norm(out[i])
        if length > 0:
            out[i] /= length
    return out


def test_smooth_normals_match_naive_loop():
    rng = np.random.default_rng(0)
    v, f = uv_sphere(1.0, 12, 8)
    v = v + 0.05 * rng.standard_normal(v.shape).astype(np.float32)
    batch = np.stack([v, v * 1.3 + 0.2, v[:, [1, 0, 2]]])  # (3, V, 3), the last one mirrored
    got = smooth_vertex_normals(batch.reshape(1, 3, -1, 3), f)  # (1, 3, V, 3)
    assert got.shape == (1, 3, len(v), 3) and got.dtype == np.float32
    for i in range(3):
        np.testing.assert_allclose(got[0, i], _naive_normals(batch[i], f), atol=1e-5)


def test_smooth_normals_point_outwards_and_isolated_vertex_is_zero():
    v, f = uv_sphere(2.0, 24, 12)
    v = np.concatenate([v, [[5.0, 5.0, 5.0]]])  # an extra vertex in no face
    n = smooth_vertex_normals(v, f)
    cos = np.sum(n[:-1] * v[:-1], axis=-1) / np.linalg.norm(v[:-1], axis=-1)
    assert cos.min() > 0.99
    np.testing.assert_array_equal(n[-1], 0.0)


def test_primitives_face_outwards():
    for v, f in (capsule(0.2, 1.7, 24, 24), open_cone(segments=24, rings=8)):
        n = smooth_vertex_normals(v, f)
        radial = v.copy()
        radial[:, 2] = 0.0  # away from the Z axis
        assert np.mean(np.sum(n * radial, axis=-1) > 0) > 0.95


def test_normals_reject_bad_faces():
    v, f = uv_sphere(1.0, 8, 4)
    with pytest.raises(LoosefitInputError, match="faces"):
        smooth_vertex_normals(v, f + len(v))


# -- camera -----------------------------------------------------------------------------------


def test_look_at_puts_target_on_negative_z():
    view = look_at((0.0, -3.0, 1.0), (0.0, 0.0, 1.0))
    np.testing.assert_allclose(view @ [0.0, -3.0, 1.0, 1.0], [0, 0, 0, 1], atol=1e-6)
    np.testing.assert_allclose(view @ [0.0, 0.0, 1.0, 1.0], [0, 0, -3, 1], atol=1e-6)
    np.testing.assert_allclose(view @ [1.0, 0.0, 1.0, 1.0], [1, 0, -3, 1], atol=1e-6)  # +X is right
    with pytest.raises(LoosefitInputError):
        look_at((0, 0, 5), (0, 0, 0))  # looking straight down with up = +Z


@pytest.mark.parametrize("name", VIEW_NAMES)
@pytest.mark.parametrize("aspect", [1.0, 0.5, 2.0])
def test_frame_views_fit_the_box(name, aspect):
    lo, hi = np.array([-0.4, -0.3, 0.0]), np.array([0.5, 0.3, 1.8])
    [(view, proj)] = frame_views([name], lo, hi, aspect)
    corners = np.array(
        [[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    )
    clip = corners @ (proj @ view).T  # (8, 4)
    ndc = clip[:, :3] / clip[:, 3:]
    assert np.abs(ndc).max() <= 1.0 + 1e-5
    assert np.abs(ndc[:, :2]).max() > 0.8  # snug, not far away


def test_named_views_are_where_documented():
    front = named_view("front").direction()
    assert front[1] < -0.9  # at -Y, in front of an avatar that faces -Y
    assert named_view("side").direction()[0] > 0.9
    assert named_view("back").direction()[1] > 0.9
    assert named_view("top").direction()[2] > 0.99
    with pytest.raises(LoosefitInputError, match="view name"):
        named_view("nope")


def test_perspective_maps_near_and_far():
    p = perspective(40.0, 1.5, 0.5, 20.0)
    for depth, ndc in ((0.5, -1.0), (20.0, 1.0)):
        clip = p @ [0.0, 0.0, -depth, 1.0]
        assert clip[2] / clip[3] == pytest.approx(ndc, abs=1e-5)


def test_camera_track_follow_moves_with_smoothed_centre():
    T = 30
    centres = np.zeros((T, 3))
    centres[:, 0] = np.linspace(0.0, 3.0, T)
    lo, hi = centres + [-0.3, -0.3, 0.0], centres + [0.3, 0.3, 1.7]
    fixed = camera_track(["front"], lo, hi)
    follow = camera_track(["front"], lo, hi, follow_centres=centres, follow_sigma_frames=2.0)
    assert np.allclose(fixed.eye[0], fixed.eye[-1])
    np.testing.assert_allclose(follow.target[:, 0], centres[:, 0], atol=0.05)
    dist = np.linalg.norm(follow.eye[:, 0] - follow.target, axis=-1)
    np.testing.assert_allclose(dist, dist[0], rtol=1e-5)  # no zooming
    assert dist[0] < np.linalg.norm(fixed.eye[0, 0] - fixed.target[0])  # closer than a static fit
    np.testing.assert_allclose(smooth_track(centres[:, :2], 0.0), centres[:, :2])


# -- renderer ---------------------------------------------------------------------------------


def test_sphere_in_centre_and_corners_empty(renderer):
    image = renderer.render_frame([_sphere()], "front")
    assert image.shape == (SIZE, SIZE, 3) and image.dtype == np.uint8
    centre = image[SIZE // 2, SIZE // 2].astype(int)
    assert centre[0] > centre[1] + 40  # the red sphere, not the grey floor or background
    for y, x in ((0, 0), (0, SIZE - 1)):
        assert _is_background(image[y, x], renderer.config)
    for y, x in ((SIZE - 1, 0), (SIZE - 1, SIZE - 1)):
        r, g, b = image[y, x].astype(int)
        assert max(r, g, b) - min(r, g, b) < 12  # grey floor or background


def test_moving_vertices_change_the_image(renderer):
    # The sphere moves right frame by frame; every frame must show it where it is.
    scene = [_sphere(frames=[[x, 0.0, 0.0] for x in (-0.4, 0.0, 0.4)])]
    frames = list(renderer.render_sequence(scene))
    assert len(frames) == 3
    for a, b in zip(frames, frames[1:], strict=False):
        assert np.abs(a.astype(int) - b).mean() > 1.0
    red_x = [np.nonzero((f[..., 0].astype(int) - f[..., 1]) > 60)[1].mean() for f in frames]
    assert red_x[0] < red_x[1] < red_x[2]
    # Frames rendered one by one, out of order, equal the sequence's (no stale buffers).
    for t in (2, 0, 1):
        np.testing.assert_array_equal(renderer.render_frame(scene, 0, frame=t), frames[t])


def test_views_tile_side_by_side(renderer):
    scene = [_sphere()]
    [image] = list(renderer.render_sequence(scene, views=["front", "side"]))
    assert image.shape == (SIZE, 2 * SIZE, 3)
    front = renderer.render_frame(scene, "front")
    np.testing.assert_array_equal(image[:, :SIZE], front)


def test_labels_are_drawn():
    with _renderer(labels=True, frame_counter=True) as r:
        scene = [_sphere()]
        labelled = next(iter(r.render_sequence(scene, title="t")))
        plain = r.render_frame(scene, 0)
    assert labelled.shape == plain.shape
    assert not np.array_equal(labelled, plain)


def test_shadows_on_and_off_differ(renderer):
    scene = [_sphere(center=(0.0, 0.0, 0.7))]
    with _renderer(shadows=False) as flat:
        no_shadow = flat.render_frame(scene, "front")
    shadow = renderer.render_frame(scene, "front")
    diff = shadow.astype(int) - no_shadow
    assert (diff < -20).sum() > 30  # a patch of floor got darker
    assert (diff > 5).sum() < 10  # and nothing got brighter


def test_vertex_colors_show_up(renderer):
    sphere = _sphere()
    green = np.tile([0.1, 0.9, 0.1], (sphere.num_vertices, 1))
    scene = [RenderMesh(sphere.faces, sphere.vertices, vertex_colors=green)]
    r, g, b = renderer.render_frame(scene, "front")[SIZE // 2, SIZE // 2].astype(int)
    assert g > r + 40 and g > b + 40
    per_frame = np.stack([green, green[:, [1, 0, 2]]])  # (T, V, 3): green, then red
    moving = RenderMesh(sphere.faces, np.repeat(sphere.vertices, 2, 0), vertex_colors=per_frame)
    r, g, b = renderer.render_frame([moving], "front", frame=1)[SIZE // 2, SIZE // 2].astype(int)
    assert r > g + 40


def test_back_faces_are_lit_and_tinted(renderer):
    # A square of cloth in the XZ plane, once facing the front camera, once facing away.
    v = np.array([[-0.5, 0, 0.5], [0.5, 0, 0.5], [0.5, 0, 1.5], [-0.5, 0, 1.5]], np.float32)
    facing = np.array([[0, 1, 2], [0, 2, 3]])  # counter-clockwise seen from -Y: faces the camera
    away = facing[:, ::-1]
    colors = []
    for faces in (facing, away):
        image = renderer.render_frame([RenderMesh(faces, v, color=(0.8, 0.8, 0.8))], "front")
        colors.append(image[SIZE // 2, SIZE // 2].astype(int))
    front, back = colors
    assert back.sum() > 3 * 40  # lit, not black, and not culled
    assert not _is_background(np.array(back, np.uint8), renderer.config)
    assert np.abs(front - back).max() > 15  # a visibly different shade


def test_follow_keeps_the_character_centred():
    xs = np.linspace(-2.0, 2.0, 12)
    scene = [_sphere(frames=[[x, 0.0, 0.0] for x in xs])]
    scene[0].role = "body"
    with _renderer(follow=True, follow_sigma_frames=1.0) as r:
        frames = [r.render_frame(scene, 0, frame=t) for t in (0, 11)]
    for f in frames:
        cols = np.nonzero((f[..., 0].astype(int) - f[..., 1]) > 60)[1]
        assert abs(cols.mean() - SIZE / 2) < SIZE * 0.1


def test_static_and_animated_meshes_mix(renderer):
    floor_ball = _sphere(center=(0.6, 0.0, 0.3), radius=0.3)  # (V, 3): static
    mover = _sphere(frames=[[0, 0, 0], [0, 0, 0.3]])
    frames = list(renderer.render_sequence([floor_ball, mover]))
    assert len(frames) == 2 and not np.array_equal(frames[0], frames[1])


def test_bad_scenes_are_rejected(renderer):
    v, f = uv_sphere(1.0, 8, 4)
    with pytest.raises(LoosefitInputError, match="faces"):
        RenderMesh(f + 1000, v)
    with pytest.raises(LoosefitInputError, match="vertices"):
        RenderMesh(f, np.full_like(v, np.nan))
    with pytest.raises(LoosefitInputError, match="vertex_colors"):
        RenderMesh(f, v, vertex_colors=np.zeros((3, 3)))
    a = RenderMesh(f, np.repeat(v[None], 3, 0))
    b = RenderMesh(f, np.repeat(v[None], 2, 0))
    with pytest.raises(LoosefitInputError, match="frames"):
        renderer.render_sequence([a, b])
    with pytest.raises(LoosefitInputError, match="view name"):
        RenderConfig(views=("frnt",))


def test_close_is_idempotent():
    r = _renderer()
    r.close()
    r.close()
    with pytest.raises(RuntimeError, match="closed"):
        r.render_frame([_sphere()])
