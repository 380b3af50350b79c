"""Headless OpenGL renderer (moderngl over EGL) for body + garment sequences.

Each frame: smooth normals are recomputed in numpy and written into persistent
vertex buffers, a depth-only pass renders the key light's shadow map, then each
view draws a checkered floor and the meshes with two-sided Blinn-Phong shading
into a multisampled framebuffer, which is resolved and read back. Views are
tiled side by side and optionally labelled.

Example::

    scene = [RenderMesh(body_faces, body_verts, role="body"), RenderMesh(skirt_faces, skirt_verts)]
    with Renderer(RenderConfig(views=("front", "side"))) as renderer:
        for image in renderer.render_sequence(scene, title="clip"):  # (H, 2 W, 3) uint8
            ...
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from loosefit.errors import LoosefitInputError
from loosefit.render import shaders
from loosefit.render.camera import CameraTrack, CameraView, camera_track, light_track, named_view
from loosefit.render.geometry import NormalPlan
from loosefit.render.gpu import GpuMesh, set_uniform, write_uniform_matrix

RGB = tuple[float, float, float]


@dataclass
class RenderConfig:
    """Everything that decides how a picture looks."""

    width: int = 640  # pixels per view
    height: int = 640  # pixels per view
    views: tuple[str | CameraView, ...] = ("front",)  # names in camera.VIEW_NAMES or CameraViews
    msaa: int = 4  # samples per pixel for anti-aliasing; 0 or 1 turns it off
    shadows: bool = True  # key-light shadow map on meshes and floor
    shadow_map_size: int = 2048  # shadow map resolution, texels
    background: RGB = (0.96, 0.96, 0.97)  # sRGB in [0, 1]
    floor: bool = True  # checkerboard at z = 0, fading into the background
    floor_tile: float = 0.5  # checker square size, metres
    floor_colors: tuple[RGB, RGB] = ((0.9, 0.9, 0.91), (0.8, 0.81, 0.83))  # checker squares, sRGB
    shadow_strength: float = 0.45  # how much a full shadow darkens the floor, in [0, 1]
    light_direction: tuple[float, float, float] = (0.5, -0.7, 1.3)  # towards the key light
    key_intensity: float = 1.0  # key light strength (linear)
    ambient: float = 0.35  # hemisphere ambient from the sky; from the ground it is half of this
    fill: float = 0.25  # weak light from the camera, so no side is pitch black
    specular: float = 0.12  # highlight strength
    shininess: float = 48.0  # Blinn-Phong exponent
    body_color: RGB = (0.70, 0.72, 0.76)  # sRGB of role="body" meshes
    garment_color: RGB = (0.85, 0.42, 0.30)  # sRGB of role="garment" meshes
    other_color: RGB = (0.45, 0.62, 0.80)  # sRGB of role="other" meshes
    backface_tint: RGB = (0.70, 0.76, 0.95)  # multiplies the albedo of back faces (cloth insides)
    follow: bool = False  # camera target follows the body's smoothed XY centre
    follow_sigma_frames: float = 8.0  # Gaussian smoothing of the followed centre, frames
    labels: bool = True  # draw each view's name in its tile
    frame_counter: bool = True  # draw the title and frame number on the tiled image
    font_size: int = 16  # label text size, pixels

    def __post_init__(self) -> None:
        self.views = tuple(self.views)
        src = "RenderConfig"
        if self.width < 8 or self.height < 8:
            raise LoosefitInputError(
                src, "width, height", ">= 8 pixels", f"{self.width}x{self.height}"
            )
        if not self.views:
            raise LoosefitInputError(src, "views", "at least one view", "none")
        for v in self.views:
            named_view(v)
        if self.msaa < 0 or self.shadow_map_size < 16:
            raise LoosefitInputError(
                src, "msaa, shadow_map_size", ">= 0, >= 16", f"{self.msaa}, {self.shadow_map_size}"
            )
        if not 0.0 <= self.shadow_strength <= 1.0:
            raise LoosefitInputError(src, "shadow_strength", "in [0, 1]", str(self.shadow_strength))
        if np.linalg.norm(self.light_direction) < 1e-9 or self.light_direction[2] <= 0:
            raise LoosefitInputError(
                src, "light_direction", "a vector pointing up (z > 0)", str(self.light_direction)
            )


_ROLES = ("body", "garment", "other")


@dataclass
class RenderMesh:
    """One triangle mesh of a scene, animated or static.

    Attributes:
        faces: (F, 3) int triangle indices, counter-clockwise seen from outside.
        vertices: (T, V, 3) or (V, 3) float positions, metres; (V, 3) is a static mesh.
        role: "body", "garment" or "other": picks the colour from the config.
        color: sRGB override of the role's colour.
        vertex_colors: (V, 3) or (T, V, 3) sRGB per-vertex colours (floats in [0, 1] or
            uint8), e.g. an error heat map; they replace ``color``.
        name: a label for error messages.
        two_sided: draw back faces (tinted by ``RenderConfig.backface_tint``). None means
            yes for garments and other meshes, no for bodies: a closed body never shows its
            back faces, and culling them makes software rendering about 30% faster.
    """

    faces: np.ndarray
    vertices: np.ndarray
    role: str = "garment"
    color: RGB | None = None
    vertex_colors: np.ndarray | None = None
    name: str = "mesh"
    two_sided: bool | None = None
    _plan: NormalPlan = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        src = f"mesh '{self.name}'"
        v = np.asarray(self.vertices)
        if v.ndim == 2:
            v = v[None]
        if v.ndim != 3 or v.shape[-1] != 3 or v.shape[0] < 1:
            raise LoosefitInputError(src, "vertices", "shape (T, V, 3) or (V, 3)", str(v.shape))
        if not np.issubdtype(v.dtype, np.floating) or not np.isfinite(v).all():
            raise LoosefitInputError(
                src, "vertices", "finite floats", f"dtype {v.dtype} / NaN or inf"
            )
        self.vertices = np.ascontiguousarray(v, dtype=np.float32)  # (T, V, 3)
        self._plan = NormalPlan(self.faces, v.shape[1])
        self.faces = self._plan.faces
        if self.role not in _ROLES:
            raise LoosefitInputError(src, "role", f"one of {list(_ROLES)}", repr(self.role))
        if self.two_sided is None:
            self.two_sided = self.role != "body"
        if self.vertex_colors is not None:
            c = np.asarray(self.vertex_colors)
            c = c[None] if c.ndim == 2 else c
            T, V = self.vertices.shape[:2]
            if c.ndim != 3 or c.shape[1:] != (V, 3) or c.shape[0] not in (1, T):
                raise LoosefitInputError(
                    src,
                    "vertex_colors",
                    f"shape ({V}, 3) or ({T}, {V}, 3)",
                    str(np.shape(self.vertex_colors)),
                )
            c = c / 255.0 if c.dtype == np.uint8 else c
            self.vertex_colors = np.ascontiguousarray(np.clip(c, 0.0, 1.0), dtype=np.float32)

    @property
    def num_frames(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def num_vertices(self) -> int:
        return int(self.vertices.shape[1])


def _scene_frames(scene: Sequence[RenderMesh]) -> int:
    """Frame count T of a scene, checking that every mesh has T or 1 frames."""
    if not scene:
        raise LoosefitInputError("scene", "meshes", "at least one RenderMesh", "an empty list")
    for m in scene:
        if not isinstance(m, RenderMesh):
            raise LoosefitInputError("scene", "meshes", "RenderMesh objects", type(m).__name__)
    T = max(m.num_frames for m in scene)
    for m in scene:
        if m.num_frames not in (1, T):
            raise LoosefitInputError(
                f"mesh '{m.name}'", "vertices", f"{T} frames (or 1, static)", f"{m.num_frames}"
            )
    return T


def _frame_bounds(scene: Sequence[RenderMesh], T: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame (T, 3) min and max corners over all meshes."""
    lo = np.min([np.broadcast_to(m.vertices.min(axis=1), (T, 3)) for m in scene], axis=0)
    hi = np.max([np.broadcast_to(m.vertices.max(axis=1), (T, 3)) for m in scene], axis=0)
    return lo, hi


def _follow_centres(scene: Sequence[RenderMesh], T: int) -> np.ndarray:
    """(T, 3) mean vertex of the body meshes (of all meshes if there is no body)."""
    meshes = [m for m in scene if m.role == "body"] or list(scene)
    total = sum(np.broadcast_to(m.vertices.sum(axis=1), (T, 3)) for m in meshes)
    return total / sum(m.num_vertices for m in meshes)


@dataclass
class _Frame:
    """Everything that places the cameras and the light for one frame."""

    view_proj: list[np.ndarray]  # N (4, 4) proj @ view
    eyes: list[np.ndarray]  # N (3,) camera positions
    light_vp: np.ndarray  # (4, 4) light proj @ view
    floor_center: tuple[float, float]  # XY the floor fade is centred on
    floor_radius: float  # metres


class RenderedFrames:
    """A lazily rendered sequence of tiled images; iterate it, ``len()`` gives the frame count."""

    def __init__(self, make: Callable[[], Iterator[np.ndarray]], length: int) -> None:
        self._make, self._length = make, length

    def __len__(self) -> int:
        return self._length

    def __iter__(self) -> Iterator[np.ndarray]:
        return self._make()


class Renderer:
    """Offscreen renderer owning one standalone EGL OpenGL context.

    Use as a context manager, or call :meth:`close`. Not thread safe.

    Args:
        config: how pictures look; defaults to ``RenderConfig()``.

    Raises:
        RuntimeError: if no OpenGL 3.3 context can be created over EGL.
    """

    def __init__(self, config: RenderConfig | None = None) -> None:
        import moderngl

        self.config = cfg = config if config is not None else RenderConfig()
        try:
            self.ctx = moderngl.create_context(standalone=True, backend="egl", require=330)
        except Exception as exc:  # noqa: BLE001 - any failure here means "no usable GL"
            raise RuntimeError(
                f"could not create an OpenGL 3.3 context over EGL ({exc}); on Debian/Ubuntu "
                "install libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri for Mesa's software rasteriser"
            ) from exc
        ctx = self.ctx
        if cfg.msaa > ctx.max_samples:
            self.ctx.release()
            raise LoosefitInputError(
                "RenderConfig", "msaa", f"<= {ctx.max_samples} on this OpenGL", str(cfg.msaa)
            )
        self._mesh_prog = ctx.program(
            vertex_shader=shaders.MESH_VS, fragment_shader=shaders.MESH_FS
        )
        self._shadow_prog = ctx.program(
            vertex_shader=shaders.SHADOW_VS, fragment_shader=shaders.SHADOW_FS
        )
        self._floor_prog = ctx.program(
            vertex_shader=shaders.FLOOR_VS, fragment_shader=shaders.FLOOR_FS
        )
        corners = np.array([-1, -1, 1, -1, -1, 1, 1, 1], dtype=np.float32)
        self._floor_vbo = ctx.buffer(corners.tobytes())
        self._floor_vao = ctx.vertex_array(self._floor_prog, [(self._floor_vbo, "2f", "in_corner")])
        S = cfg.shadow_map_size
        self._shadow_tex = ctx.depth_texture((S, S))
        self._shadow_tex.compare_func = "<="  # sampler2DShadow with hardware 2x2 PCF
        self._shadow_tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self._shadow_tex.repeat_x = self._shadow_tex.repeat_y = False
        self._shadow_fbo = ctx.framebuffer(depth_attachment=self._shadow_tex)
        size = (cfg.width, cfg.height)
        self._resolve_fbo = ctx.framebuffer(
            color_attachments=[ctx.renderbuffer(size, 3)],
            depth_attachment=ctx.depth_renderbuffer(size),
        )
        if cfg.msaa > 1:
            self._draw_fbo = ctx.framebuffer(
                color_attachments=[ctx.renderbuffer(size, 4, samples=cfg.msaa)],
                depth_attachment=ctx.depth_renderbuffer(size, samples=cfg.msaa),
            )
        else:
            self._draw_fbo = self._resolve_fbo
        self._slots: list[GpuMesh] = []
        self._font = ImageFont.load_default(size=cfg.font_size)
        self._static_uniforms()

    # -- lifetime ---------------------------------------------------------------------------

    def close(self) -> None:
        """Release every GPU object and the context (idempotent)."""
        if getattr(self, "ctx", None) is None:
            return
        with self.ctx:
            for slot in self._slots:
                slot.release()
            self._slots = []
        self.ctx.release()
        self.ctx = None

    def __enter__(self) -> Renderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- public API -------------------------------------------------------------------------

    def render_frame(
        self,
        meshes: Sequence[RenderMesh],
        camera: int | str | CameraView | tuple[np.ndarray, np.ndarray] = 0,
        frame: int = 0,
    ) -> np.ndarray:
        """Render one frame from one camera.

        Args:
            meshes: the scene; animated meshes show frame ``frame``.
            camera: an index into ``config.views``, a view name, a :class:`CameraView`
                (these are framed on the bounds of all frames, as in :meth:`render_sequence`),
                or explicit ``(view (4, 4), proj (4, 4))`` matrices.
            frame: which frame of the scene to draw.

        Returns:
            (H, W, 3) uint8 image, without labels.
        """
        T = _scene_frames(meshes)
        if not 0 <= frame < T:
            raise LoosefitInputError("render_frame", "frame", f"in [0, {T})", str(frame))
        if isinstance(camera, tuple):
            view, proj = (np.asarray(m, dtype=np.float64) for m in camera)
            if view.shape != (4, 4) or proj.shape != (4, 4):
                raise LoosefitInputError(
                    "render_frame", "camera", "(4, 4) view and proj", "other shapes"
                )
            layout = self._layout(meshes, T, [self.config.views[0]])
            fr = self._frame(layout, frame)
            fr.view_proj, fr.eyes = [proj @ view], [np.linalg.inv(view)[:3, 3]]
        else:
            if isinstance(camera, int):
                if not 0 <= camera < len(self.config.views):
                    raise LoosefitInputError(
                        "render_frame",
                        "camera",
                        f"a view index < {len(self.config.views)}",
                        str(camera),
                    )
                camera = self.config.views[camera]
            fr = self._frame(self._layout(meshes, T, [camera]), frame)
        return self._draw(meshes, frame, fr)[0]

    def render_sequence(
        self,
        scene: Sequence[RenderMesh],
        views: Sequence[str | CameraView] | None = None,
        *,
        title: str | None = None,
        fps: float | None = None,
        frames: Sequence[int] | None = None,
    ) -> RenderedFrames:
        """Render every frame of a scene from several views, tiled side by side.

        The cameras are fitted once to the whole sequence (or follow the body, see
        ``RenderConfig.follow``), so they never jump.

        Args:
            scene: meshes with T frames each (or 1, static).
            views: names or :class:`CameraView` objects; defaults to ``config.views``.
            title: text drawn top-left with the frame counter.
            fps: if given, the counter also shows the time in seconds.
            frames: which frames to render (default all, in order).

        Returns:
            a sized iterable of (H, N * W, 3) uint8 images, rendered as it is iterated.
        """
        T = _scene_frames(scene)
        frames = list(range(T)) if frames is None else [int(t) for t in frames]
        bad = [t for t in frames if not 0 <= t < T]
        if bad:
            raise LoosefitInputError(
                "render_sequence", "frames", f"indices in [0, {T})", str(bad[:5])
            )
        views = self.config.views if views is None else tuple(views)
        if not views:
            raise LoosefitInputError("render_sequence", "views", "at least one view", "none")
        layout = self._layout(scene, T, views)

        def generate() -> Iterator[np.ndarray]:
            for t in frames:
                images = self._draw(scene, t, self._frame(layout, t))
                header = None
                if self.config.frame_counter:
                    header = f"frame {t + 1}/{T}" + (f"   {t / fps:.2f} s" if fps else "")
                    header = f"{title}   {header}" if title else header
                elif title:
                    header = title
                yield self._compose(images, layout[0].names, header)

        return RenderedFrames(generate, len(frames))

    # -- cameras and light ------------------------------------------------------------------

    def _layout(
        self, scene: Sequence[RenderMesh], T: int, views: Sequence[str | CameraView]
    ) -> tuple[CameraTrack, np.ndarray, float]:
        """Camera track, (T, 4, 4) light view-projections and the floor radius of a sequence."""
        cfg = self.config
        lo, hi = _frame_bounds(scene, T)
        centres = _follow_centres(scene, T) if cfg.follow else None
        track = camera_track(
            views,
            lo,
            hi,
            cfg.width / cfg.height,
            follow_centres=centres,
            follow_sigma_frames=cfg.follow_sigma_frames,
        )
        light_view, light_proj = light_track(cfg.light_direction, lo, hi, cfg.shadow_map_size)
        light_vp = light_proj @ light_view  # (T, 4, 4)
        rel = np.concatenate([lo - track.target, hi - track.target])[:, :2]  # (2T, 2)
        floor_radius = max(2.0, 2.5 * float(np.abs(rel).max()))
        return track, light_vp, floor_radius

    def _frame(self, layout: tuple[CameraTrack, np.ndarray, float], t: int) -> _Frame:
        track, light_vp, floor_radius = layout
        return _Frame(
            view_proj=[track.proj[i] @ track.view[t, i] for i in range(len(track.names))],
            eyes=list(track.eye[t]),
            light_vp=light_vp[t],
            floor_center=(float(track.target[t, 0]), float(track.target[t, 1])),
            floor_radius=floor_radius,
        )

    # -- drawing ----------------------------------------------------------------------------

    def _static_uniforms(self) -> None:
        cfg = self.config
        L = np.asarray(cfg.light_direction, dtype=np.float64)
        L /= np.linalg.norm(L)
        mp, fp = self._mesh_prog, self._floor_prog
        for prog in (mp, fp):
            set_uniform(prog, "u_shadow_map", 0)
            set_uniform(prog, "u_shadows", int(cfg.shadows))
            set_uniform(prog, "u_shadow_texel", 1.0 / cfg.shadow_map_size)
        set_uniform(mp, "u_shadow_bias", 0.006)
        set_uniform(fp, "u_shadow_bias", 0.0)
        set_uniform(mp, "u_light_dir", tuple(L))
        set_uniform(mp, "u_key", (cfg.key_intensity,) * 3)
        set_uniform(mp, "u_sky", (cfg.ambient,) * 3)
        set_uniform(mp, "u_ground", (cfg.ambient / 2,) * 3)
        set_uniform(mp, "u_fill", cfg.fill)
        set_uniform(mp, "u_specular", cfg.specular)
        set_uniform(mp, "u_shininess", cfg.shininess)
        set_uniform(mp, "u_backface_tint", tuple(cfg.backface_tint))
        set_uniform(fp, "u_tile", cfg.floor_tile)
        set_uniform(fp, "u_tile_a", tuple(cfg.floor_colors[0]))
        set_uniform(fp, "u_tile_b", tuple(cfg.floor_colors[1]))
        set_uniform(fp, "u_background", tuple(cfg.background))
        set_uniform(fp, "u_shadow_strength", cfg.shadow_strength)

    def _sync(self, scene: Sequence[RenderMesh], t: int) -> None:
        """Make the GPU buffers hold frame ``t`` of ``scene`` (re-using slots of the same size)."""
        cfg = self.config
        colors = {"body": cfg.body_color, "garment": cfg.garment_color, "other": cfg.other_color}
        for i, mesh in enumerate(scene):
            size = (mesh.num_vertices, len(mesh.faces), mesh.two_sided)
            if i < len(self._slots) and self._slots[i].size != size:
                self._slots[i].release()
                self._slots[i] = GpuMesh(self.ctx, self._mesh_prog, self._shadow_prog, *size)
            elif i >= len(self._slots):
                self._slots.append(GpuMesh(self.ctx, self._mesh_prog, self._shadow_prog, *size))
            color = tuple(mesh.color) if mesh.color is not None else colors[mesh.role]
            self._slots[i].sync(mesh, t, color)
        for slot in self._slots[len(scene) :]:
            slot.release()
        del self._slots[len(scene) :]

    def _draw(self, scene: Sequence[RenderMesh], t: int, fr: _Frame) -> list[np.ndarray]:
        """Render frame ``t`` from every camera of ``fr``; returns N (H, W, 3) uint8 images."""
        if self.ctx is None:
            raise RuntimeError("Renderer is closed")
        with self.ctx:  # make our context current: several renderers may coexist
            return self._draw_current(scene, t, fr)

    def _draw_current(self, scene: Sequence[RenderMesh], t: int, fr: _Frame) -> list[np.ndarray]:
        import moderngl

        cfg, ctx = self.config, self.ctx
        self._sync(scene, t)
        ctx.enable(moderngl.DEPTH_TEST)
        if cfg.shadows:
            self._shadow_fbo.use()
            self._shadow_fbo.clear(depth=1.0)
            ctx.polygon_offset = (1.5, 4.0)
            write_uniform_matrix(self._shadow_prog, "u_light_vp", fr.light_vp)
            ctx.cull_face = "front"  # closed meshes cast from their back faces: no acne
            for slot in self._slots:
                self._cull(not slot.two_sided)
                slot.shadow_vao.render(moderngl.TRIANGLES)
            ctx.cull_face = "back"
            ctx.polygon_offset = (0.0, 0.0)
        self._shadow_tex.use(location=0)
        for prog in (self._mesh_prog, self._floor_prog):
            write_uniform_matrix(prog, "u_light_vp", fr.light_vp)
        set_uniform(self._floor_prog, "u_floor_center", fr.floor_center)
        set_uniform(self._floor_prog, "u_floor_radius", fr.floor_radius)
        set_uniform(self._floor_prog, "u_floor_half", fr.floor_radius * 1.05)
        images = []
        for vp, eye in zip(fr.view_proj, fr.eyes, strict=True):
            self._draw_fbo.use()
            self._draw_fbo.clear(*cfg.background, 1.0, depth=1.0)
            write_uniform_matrix(self._mesh_prog, "u_vp", vp)
            set_uniform(self._mesh_prog, "u_eye", tuple(float(x) for x in eye))
            for slot in self._slots:
                self._cull(not slot.two_sided)  # cloth is single-layer: draw both sides
                slot.vao.render(moderngl.TRIANGLES)
            self._cull(False)
            if cfg.floor and eye[2] > 0.0:  # from below, the floor would hide everything
                # Drawn last, so the early depth test skips the floor hidden behind the meshes.
                write_uniform_matrix(self._floor_prog, "u_vp", vp)
                self._floor_vao.render(moderngl.TRIANGLE_STRIP)
            if self._draw_fbo is not self._resolve_fbo:
                ctx.copy_framebuffer(self._resolve_fbo, self._draw_fbo)
            data = self._resolve_fbo.read(components=3, alignment=1)
            image = np.frombuffer(data, dtype=np.uint8).reshape(cfg.height, cfg.width, 3)
            images.append(np.ascontiguousarray(image[::-1]))  # GL rows run bottom-up
        return images

    def _cull(self, on: bool) -> None:
        import moderngl

        if on:
            self.ctx.enable(moderngl.CULL_FACE)
        else:
            self.ctx.disable(moderngl.CULL_FACE)

    def _compose(
        self, images: list[np.ndarray], names: list[str], header: str | None
    ) -> np.ndarray:
        """Tile N (H, W, 3) views side by side into (H, N W, 3) and draw the labels."""
        tiled = np.concatenate(images, axis=1)  # (H, N W, 3)
        cfg = self.config
        if not ((cfg.labels and len(names) > 0) or header):
            return tiled
        bright = float(np.dot(cfg.background, (0.299, 0.587, 0.114))) > 0.5
        ink = (40, 40, 45) if bright else (235, 235, 235)
        pil = Image.fromarray(tiled)
        draw = ImageDraw.Draw(pil)
        pad = max(4, cfg.font_size // 2)
        if cfg.labels:
            for i, name in enumerate(names):
                draw.text(
                    (i * cfg.width + pad, cfg.height - pad),
                    name,
                    fill=ink,
                    font=self._font,
                    anchor="ld",
                )
        if header:
            draw.text((pad, pad), header, fill=ink, font=self._font, anchor="la")
        return np.asarray(pil)
