"""The viewer: a local web page (viser) playing garment sequences on their bodies.

:class:`Viewer` serves the sequences (:mod:`loosefit.view.scene`) to any browser that
opens its URL: the body and the garment of each, side by side or overlaid, each shown
or hidden; play, pause, a frame slider, the speed, a camera that follows the body; the
garment coloured by its distance to a reference sequence, its edge strain or its depth
inside the body (:mod:`loosefit.view.colouring`) with a colour bar; the frame's RMSE.

Only the shown frame travels: each frame, every visible mesh gets that frame's vertices
(viser updates the browser's vertex buffers in place), so a sequence of thousands of
frames opens as fast as it is read and posed. A colouring draws each garment as one mesh
per colour bin (viser's meshes take one colour each). Nothing here needs a display: the
server prints its URL and any browser, here or forwarded over SSH, shows it.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.eval.metrics import rmse_per_frame
from loosefit.geometry.query import Surface
from loosefit.view import colouring
from loosefit.view.config import COLOURINGS, LAYOUTS, ViewerConfig
from loosefit.view.scene import ViewSequence

SCALE_OF = {"plain": None, "error": "error", "strain": "strain", "inside": "inside"}
GARMENT_COLOURS = ((70, 130, 200), (230, 120, 40), (80, 170, 90), (170, 80, 170), (200, 60, 60))
BODY_COLOUR = (205, 200, 195)
# The floor: a square of grid this much wider than the shown bodies' spread, under them and
# moved with them in whole metres (its lines stay put on the ground). A browser drawing in
# software pays for every pixel of floor (viser's grid shader): a 20 m floor to the horizon
# cost it about 40% of a frame more (docs/use/VIEWER.md).
FLOOR_SIZE = 6.0  # m
MAX_UPDATES_PER_S = 60.0  # faster playback skips frames rather than flood the browser
PANEL_EVERY_S = 0.25  # while playing, the slider and figures follow this often
PANEL_FOLDERS = ("Playback", "Sequences", "Colour")  # the panel's folders, top to bottom


class Viewer:
    """A running viewer of sequences of one garment and motion.

    Args:
        sequences: what to show (:func:`~loosefit.view.scene.from_animated`).
        config: how to serve and start.

    The scene and the whole panel are built before the constructor returns: whatever
    announces :attr:`url` (``loosefit view``'s line, :meth:`loosefit.AnimatedGarment.view`) does so
    once a browser opening it gets every control.

    Attributes:
        url: where a browser opens it.
        port: the port it got (``config.port`` or the next free one).
        server: the :class:`viser.ViserServer`.
        floor: the floor's grid (a viser ``GridHandle``).
    """

    def __init__(self, sequences: Sequence[ViewSequence], config: ViewerConfig | None = None):
        try:
            import viser
        except ImportError as exc:  # the optional extra
            raise LoosefitInputError(
                "loosefit view",
                "viser",
                "the viewer's library (pip install 'loosefit[viewer]')",
                "not installed",
            ) from exc
        self.config = config = config or ViewerConfig()
        config.validate(len(sequences))
        self.sequences = list(sequences)
        self.num_frames = self.sequences[0].num_frames
        self.fps = self.sequences[0].fps
        self.frame = 0
        self.playing = config.play
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._surfaces: dict[int, Surface] = {}  # id(body) -> the body's BVH (inside)
        self._inside: dict[tuple[int, int], np.ndarray] = {}  # (sequence, frame) -> depths
        self._follow_at: np.ndarray | None = None
        self.visible = [True] * len(self.sequences)  # the panel's checkboxes
        self.bodies_on = True  # the panel's "bodies"
        self.server = viser.ViserServer(
            host=config.host, port=config.port, verbose=False, label="loosefit"
        )
        self.server.gui.configure_theme(show_share_button=False)  # no tunnel off the machine
        self.port = int(self.server.get_port())
        shown = "localhost" if config.host in ("0.0.0.0", "127.0.0.1", "::") else config.host
        self.url = f"http://{shown}:{self.port}"
        if config.pixel_ratio is not None:  # viser's page reads it from its URL
            self.url += f"/?fixedDpr={config.pixel_ratio:g}"
        self._build_scene()
        self._build_panel()
        self.set_frame(0)
        self._thread = threading.Thread(target=self._play_loop, name="loosefit-view", daemon=True)
        self._thread.start()

    # -- the scene ------------------------------------------------------------------------

    def _build_scene(self) -> None:
        scene = self.server.scene
        scene.set_up_direction("+z")
        scene.world_axes.visible = False
        # Lit by plain lights: the image-based light of an environment map halves the frame
        # rate of a browser drawing WebGL in software (measured); from the front, above.
        scene.configure_environment_map(None)
        scene.configure_default_lights(enabled=False)
        scene.add_light_hemisphere(
            "/lights/sky", sky_color=(255, 255, 255), ground_color=(120, 110, 100), intensity=1.2
        )
        scene.add_light_directional("/lights/key", intensity=2.0, position=(1.5, -3.0, 4.0))
        scene.add_light_directional("/lights/back", intensity=0.8, position=(-1.0, 3.0, 2.0))
        floor = float(min(s.body[0, :, 2].min() for s in self.sequences))
        self.floor = scene.add_grid(
            "/floor",
            width=FLOOR_SIZE,
            height=FLOOR_SIZE,
            position=(0.0, 0.0, floor),
            cell_size=0.25,
            section_size=1.0,
        )
        bins = self.config.bins
        self.nodes, self.bodies, self.garments, self.bin_meshes, self.labels = [], [], [], [], []
        self._label_z: list[float] = []
        for i, seq in enumerate(self.sequences):
            node = scene.add_frame(f"/seq{i}", show_axes=False)
            self.nodes.append(node)
            self.bodies.append(
                scene.add_mesh_simple(
                    f"/seq{i}/body",
                    seq.body[0],
                    seq.body_faces,
                    color=BODY_COLOUR,
                    cast_shadow=False,
                    receive_shadow=False,
                )
            )
            colour = GARMENT_COLOURS[i % len(GARMENT_COLOURS)]
            self.garments.append(
                scene.add_mesh_simple(
                    f"/seq{i}/garment",
                    seq.garment[0],
                    seq.template.faces,
                    color=colour,
                    side="double",
                    cast_shadow=False,
                    receive_shadow=False,
                )
            )
            self.bin_meshes.append(
                [
                    scene.add_mesh_simple(
                        f"/seq{i}/colour/{k}",
                        np.zeros((3, 3), np.float32),
                        np.array([[0, 1, 2]], np.uint32),
                        color=tuple(int(c) for c in rgb),
                        side="double",
                        cast_shadow=False,
                        receive_shadow=False,
                        visible=False,
                    )
                    for k, rgb in enumerate(colouring.bin_colours("viridis", bins))
                ]
            )
            self._label_z.append(float(seq.body[:, :, 2].max()) + 0.2)
            self.labels.append(scene.add_label(f"/seq{i}/label", seq.name))
        self._place()
        centre = self._follow_point()
        self.server.initial_camera.position = tuple(centre + np.array([0.4, -2.6, 0.4]))
        self.server.initial_camera.look_at = tuple(centre)

    def _place(self) -> None:
        """Each shown sequence's offset (side by side along x, centred) and which bodies show:
        overlaid, one body per distinct pose."""
        shown = [i for i in range(len(self.sequences)) if self.visible[i]]
        side = self.config.layout == "side by side"
        for slot, i in enumerate(shown):
            x = (slot - (len(shown) - 1) / 2) * self.config.spacing if side else 0.0
            self.nodes[i].position = (x, 0.0, 0.0)
        width = FLOOR_SIZE + (self.config.spacing * (len(shown) - 1) if side else 0.0)
        if self.floor.width != width:
            self.floor.width = width
        seen: set[int] = set()
        for i, body in enumerate(self.bodies):
            key = id(self.sequences[i].body)
            body.visible = self.bodies_on and i in shown and (side or key not in seen)
            if i in shown:
                seen.add(key)
            self.labels[i].visible = i in shown and side

    # -- the panel ------------------------------------------------------------------------

    def _build_panel(self) -> None:
        gui, c, T = self.server.gui, self.config, self.num_frames
        playback, sequences, colour = PANEL_FOLDERS
        with gui.add_folder(playback):
            self.play_button = gui.add_button("Pause" if self.playing else "Play")
            self.slider = gui.add_slider("frame", 0, max(T - 1, 1), 1, 0, disabled=T == 1)
            self.speed = gui.add_slider("speed", 0.1, 4.0, 0.05, float(c.speed))
            self.follow_box = gui.add_checkbox("camera follows", c.follow)
            self.loop_box = gui.add_checkbox("loop", c.loop)
            self.time_text = gui.add_markdown("")
        with gui.add_folder(sequences):
            self.layout = gui.add_dropdown("layout", LAYOUTS, initial_value=c.layout)
            self.body_box = gui.add_checkbox("bodies", True)
            self.seq_boxes = [gui.add_checkbox(s.name, True) for s in self.sequences]
        with gui.add_folder(colour):
            modes = [k for k in COLOURINGS if len(self.sequences) > 1 or k != "error"]
            self.mode = gui.add_dropdown(
                "colour by", [COLOURINGS[k] for k in modes], initial_value=COLOURINGS[c.colouring]
            )
            names = [s.name for s in self.sequences]
            self.reference = gui.add_dropdown(
                "reference", names, initial_value=names[c.reference], visible=len(names) > 1
            )
            self.scale_max = gui.add_number("scale max", 1.0, min=1e-6, step=0.1)
            self.colour_bar = gui.add_html("")
            self.stats = gui.add_markdown("")
        self._wire_panel()
        self._mode_changed()

    @property
    def panel_labels(self) -> list[str]:
        """The labels a browser shows in the panel as it is now: the folders' and the shown
        controls' (a headless screenshot waits for them: the panel has arrived)."""
        controls = [
            self.play_button,
            self.slider,
            self.speed,
            self.follow_box,
            self.loop_box,
            self.layout,
            self.body_box,
            *self.seq_boxes,
            self.mode,
            self.reference,
            self.scale_max,
        ]
        return list(PANEL_FOLDERS) + [c.label for c in controls if c.visible]

    def _wire_panel(self) -> None:
        @self.play_button.on_click
        def _(_) -> None:
            self.pause() if self.playing else self.play()

        @self.slider.on_update
        def _(_) -> None:
            if int(self.slider.value) != self.frame:
                self.set_frame(int(self.slider.value))

        @self.layout.on_update
        def _(_) -> None:
            self.config.layout = self.layout.value
            self._refresh()

        @self.body_box.on_update
        def _(_) -> None:
            self.bodies_on = bool(self.body_box.value)
            self._refresh()

        for i, box in enumerate(self.seq_boxes):
            box.on_update(lambda _, i=i: self.set_visible(i, self.seq_boxes[i].value))

        @self.mode.on_update
        def _(_) -> None:
            self._mode_changed()

        @self.reference.on_update
        def _(_) -> None:
            self._refresh()

        @self.scale_max.on_update
        def _(_) -> None:
            self._bar()
            self._refresh()

    def _mode_changed(self) -> None:
        key = self._scale_key()
        self.scale_max.visible = self.colour_bar.visible = key is not None
        if key is not None:
            scale = colouring.SCALES[key]
            self.scale_max.value = round(scale.vmax * scale.factor, 6)
            colours = colouring.bin_colours(scale.colormap, self.config.bins)
            for meshes in self.bin_meshes:
                for mesh, rgb in zip(meshes, colours, strict=True):
                    mesh.color = tuple(int(v) for v in rgb)
            self._bar()
        self._refresh()

    def _scale_key(self) -> str | None:
        """The shown colouring's key of colouring.SCALES (None: plain)."""
        short = next(k for k, label in COLOURINGS.items() if label == self.mode.value)
        return SCALE_OF[short]

    def _bar(self) -> None:
        key = self._scale_key()
        if key is not None:
            scale = colouring.SCALES[key]
            vmax = float(self.scale_max.value) / scale.factor
            self.colour_bar.content = colouring.colour_bar_html(scale, vmax, self.config.bins)

    # -- showing a frame ------------------------------------------------------------------

    def set_frame(self, t: int, panel: bool = True) -> None:
        """Show frame ``t`` (0 to ``num_frames - 1``) in every browser; ``panel``: also
        update the panel's slider and figures (playback does it a few times a second: the
        browser redraws the whole panel for each)."""
        if not 0 <= t < self.num_frames:
            raise LoosefitInputError("Viewer.set_frame", "t", f"0 to {self.num_frames - 1}", str(t))
        with self._lock, self.server.atomic():
            self.frame = int(t)
            self._show(self.frame, panel)
            if panel and int(self.slider.value) != self.frame:
                self.slider.value = self.frame

    def set_visible(self, i: int, visible: bool) -> None:
        """Show or hide sequence ``i`` (its garment and body)."""
        with self._lock:
            self.visible[i] = bool(visible)
            if self.seq_boxes[i].value != self.visible[i]:
                self.seq_boxes[i].value = self.visible[i]
            self._refresh()

    def _refresh(self) -> None:
        with self._lock, self.server.atomic():
            self._place()
            self._show(self.frame)

    def _show(self, t: int, panel: bool = True) -> None:
        key = self._scale_key()
        ref = self.sequences[[s.name for s in self.sequences].index(self.reference.value)]
        for i, seq in enumerate(self.sequences):
            shown = self.visible[i]
            self.nodes[i].visible = shown
            if not shown:
                continue
            if self.bodies[i].visible:
                self.bodies[i].vertices = seq.body[t]
            if self.labels[i].visible:  # above the head, wherever the dance went
                x, y = seq.body[t, :, :2].mean(0)
                self.labels[i].position = (float(x), float(y), self._label_z[i])
            g = seq.garment[t]
            self.garments[i].visible = key is None
            if key is None:
                self.garments[i].vertices = g
                for mesh in self.bin_meshes[i]:
                    mesh.visible = False
                continue
            values = self._values(key, i, t, ref)
            scale = colouring.SCALES[key]
            vmax = float(self.scale_max.value) / scale.factor
            faces = seq.template.faces
            bins = colouring.face_bins(faces, values, vmax, self.config.bins)
            parts = colouring.split_by_bin(faces, bins, self.config.bins)
            for mesh, (used, local) in zip(self.bin_meshes[i], parts, strict=True):
                mesh.visible = len(local) > 0
                if len(local):
                    mesh.vertices = g[used]
                    mesh.faces = local
        self._follow(t)
        if panel:
            self._panel_text(t, ref)

    def _values(self, key: str, i: int, t: int, ref: ViewSequence) -> np.ndarray:
        seq = self.sequences[i]
        if key == "error":
            return colouring.vertex_error(seq.garment[t], ref.garment[t])
        if key == "strain":
            return colouring.vertex_strain(seq.garment[t], seq.template)
        if (i, t) not in self._inside:  # the slow one (a BVH query per frame): kept
            surface = self._surfaces.get(id(seq.body))
            if surface is None:
                surface = Surface(seq.body[t], seq.body_faces, winding_number=True)
                self._surfaces[id(seq.body)] = surface
            else:
                surface.refit(seq.body[t])
            self._inside[(i, t)] = colouring.inside_depth(surface, seq.garment[t])
        return self._inside[(i, t)]

    def _follow_point(self) -> np.ndarray:
        """The middle of the shown bodies' hips at the current frame, in the scene."""
        shown = [i for i in range(len(self.sequences)) if self.visible[i]] or [0]
        points = [
            self.sequences[i].body[self.frame].mean(0) + self.nodes[i].position for i in shown
        ]
        return np.mean(points, axis=0)

    def _follow(self, t: int) -> None:
        point = self._follow_point()
        if self._follow_at is not None and self.follow_box.value:
            delta = point - self._follow_at
            delta[2] = 0.0  # horizontally: the dancer's bob would shake the view
            if np.abs(delta).max() > 1e-6:
                for client in self.server.get_clients().values():
                    # viser moves the point looked at with the camera: the view is kept
                    client.camera.position = client.camera.position + delta
        self._follow_at = point
        x, y = np.round(point[:2])  # whole metres: the grid's lines stay where they were
        if (x, y) != tuple(self.floor.position[:2]):
            self.floor.position = (float(x), float(y), float(self.floor.position[2]))

    def _panel_text(self, t: int, ref: ViewSequence) -> None:
        self.time_text.content = (
            f"frame **{t}** of {self.num_frames} · {t / self.fps:.2f} s of "
            f"{self.num_frames / self.fps:.2f} s · {self.fps:g} fps"
        )
        if len(self.sequences) < 2:
            self.stats.content = ""
            return
        others = [s for s in self.sequences if s is not ref]
        rmse = [rmse_per_frame(s.garment[t : t + 1], ref.garment[t : t + 1])[0] for s in others]
        rows = [f"| {s.name} | {100 * e:.2f} |" for s, e in zip(others, rmse, strict=True)]
        self.stats.content = f"RMSE to **{ref.name}**, this frame\n\n| | cm |\n|---|---|\n" + (
            "\n".join(rows)
        )

    # -- playback -------------------------------------------------------------------------

    def play(self) -> None:
        self.playing = True
        self.play_button.label = "Pause"

    def pause(self) -> None:
        self.playing = False
        self.play_button.label = "Play"

    def _play_loop(self) -> None:
        """Advance by the clock: at ``speed`` times the frame rate, skipping frames when a
        frame takes longer to send than its time."""
        position, last = float(self.frame), time.perf_counter()
        panel_at = last
        while not self._stop.is_set():
            rate = self.fps * float(self.speed.value)
            time.sleep(max(1.0 / rate, 1.0 / MAX_UPDATES_PER_S) / 4)
            now = time.perf_counter()
            if not self.playing:
                position, last = float(self.frame), now
                continue
            position += (now - last) * rate
            last = now
            t = int(position)
            if t >= self.num_frames:
                if not self.loop_box.value:
                    self.set_frame(self.num_frames - 1)
                    self.pause()
                    continue
                position -= self.num_frames * (t // self.num_frames)
                t = int(position)
            if t != self.frame:
                panel = now - panel_at >= PANEL_EVERY_S
                panel_at = now if panel else panel_at
                self.set_frame(t, panel)

    def wait(self) -> None:
        """Serve until interrupted (Ctrl-C), then stop."""
        try:
            while not self._stop.is_set():
                time.sleep(0.5)
        except KeyboardInterrupt:
            pass
        finally:
            self.close()

    def close(self) -> None:
        """Stop playing and serving."""
        self._stop.set()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout=5)
        self.server.stop()
