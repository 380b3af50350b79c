"""The GLSL programs compiled on a headless OpenGL context and run on a tiny picture."""

import numpy as np
import pytest

from loosefit.render import shaders

SIZE = 4  # pixels a side: every pixel covered by one full-screen triangle


@pytest.fixture(scope="module")
def ctx():
    moderngl = pytest.importorskip("moderngl")
    try:
        context = moderngl.create_context(standalone=True, backend="egl", require=330)
    except Exception as exc:  # no EGL device or driver
        pytest.skip(f"no headless OpenGL (EGL) context on this machine: {exc}")
    yield context
    context.release()


def _mesh_program(ctx):
    return ctx.program(vertex_shader=shaders.MESH_VS, fragment_shader=shaders.MESH_FS)


def _draw(ctx, prog, color, corners, **uniforms):
    """One triangle of colour ``color`` (sRGB) with clip-space corners (3, 3) over the
    whole picture, normal +z, lit by ``uniforms``: the (SIZE, SIZE, 3) picture, 0-1 floats."""
    normal = np.tile([0.0, 0.0, 1.0], (3, 1))
    data = np.hstack([corners, normal, np.tile(color, (3, 1))]).astype("f4")
    vbo = ctx.buffer(data.tobytes())
    vao = ctx.vertex_array(prog, [(vbo, "3f 3f 3f", "in_pos", "in_normal", "in_color")])
    fbo = ctx.simple_framebuffer((SIZE, SIZE), components=3)
    fbo.use()
    fbo.clear(0.0, 0.0, 0.0)
    base = dict(u_vp=np.eye(4), u_shadows=0, u_key=(0, 0, 0), u_fill=0.0, u_specular=0.0)
    base |= dict(u_eye=(0.0, 0.0, 5.0), u_light_dir=(0.0, 0.0, 1.0), u_shininess=8.0)
    for name, value in (base | uniforms).items():
        if name in prog:
            array = np.asarray(value, "f4")
            prog[name].write(array.T.tobytes() if array.ndim == 2 else array.tobytes())
            if name == "u_shadows":
                prog[name].value = int(value)
    vao.render()
    pixels = np.frombuffer(fbo.read(components=3), np.uint8).reshape(SIZE, SIZE, 3)
    for obj in (vao, vbo, fbo):
        obj.release()
    return pixels / 255.0


FRONT = np.array([[-1.0, -1.0, 0.0], [3.0, -1.0, 0.0], [-1.0, 3.0, 0.0]])  # counter-clockwise
BACK = FRONT[[0, 2, 1]]


def test_every_program_compiles_with_the_inputs_the_renderer_sets(ctx):
    mesh = _mesh_program(ctx)
    floor = ctx.program(vertex_shader=shaders.FLOOR_VS, fragment_shader=shaders.FLOOR_FS)
    shadow = ctx.program(vertex_shader=shaders.SHADOW_VS, fragment_shader=shaders.SHADOW_FS)
    for name in ("in_pos", "in_normal", "in_color", "u_vp", "u_light_vp", "u_shadow_map"):
        assert name in mesh
    for name in ("in_corner", "u_floor_center", "u_floor_half", "u_tile", "u_background"):
        assert name in floor
    assert "in_pos" in shadow and "u_light_vp" in shadow


@pytest.mark.parametrize("ambient", [1.0, 0.25])
def test_ambient_light_alone_is_lit_in_linear_space_and_written_as_srgb(ctx, ambient):
    prog = _mesh_program(ctx)
    color = np.array([0.5, 0.8, 0.2])
    got = _draw(ctx, prog, color, FRONT, u_sky=(ambient,) * 3, u_ground=(ambient,) * 3)
    # gamma 2: to linear is c^2, back to sRGB the square root
    want = np.sqrt(color**2 * ambient)
    np.testing.assert_allclose(got, np.broadcast_to(want, got.shape), atol=1.5 / 255)


def test_a_key_light_head_on_adds_its_colour_and_back_faces_are_tinted(ctx):
    prog = _mesh_program(ctx)
    color = np.array([0.6, 0.6, 0.6])
    zero = dict(u_sky=(0, 0, 0), u_ground=(0, 0, 0))
    lit = _draw(ctx, prog, color, FRONT, u_key=(0.5, 0.5, 0.5), **zero)
    np.testing.assert_allclose(lit, np.sqrt(0.36 * 0.5), atol=1.5 / 255)
    # a back face: the normal flipped (away from the light), lit only by its ambient, tinted
    back = _draw(
        ctx, prog, color, BACK, u_backface_tint=(0.5, 1.0, 1.0), u_sky=(1, 1, 1), u_ground=(1, 1, 1)
    )
    np.testing.assert_allclose(
        back[0, 0], np.sqrt(0.36 * np.array([0.5, 1.0, 1.0])), atol=1.5 / 255
    )
