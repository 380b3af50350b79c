"""What makes a frame cheaper for a browser drawing WebGL without a GPU.

Serves one sequence in this process (its bodies posed once), then for each condition opens
it in a fresh headless Chromium (SwiftShader), lets it play and counts for ``--seconds``
what ``bench/speed/viewer_fps.py`` counts: frames drawn and new frames drawn per second, the CPU
time of Chromium's GPU process (where SwiftShader draws) and of all its processes per frame
drawn. The conditions run in turn, ``--repeat`` times over, so that each is measured in
the same minutes as the others on a machine shared with other jobs. docs/use/VIEWER.md quotes
its output::

    .venv/bin/python bench/speed/viewer_levers.py out/dance1957.npz \\
        msaa+dpr=0.75,dpr=0.75,nofloor+dpr=0.75,dpr=0.5 --repeat 3

A condition is tokens joined by ``+`` (none: ``plain``, the viewer as it is with the
headless browser's defaults):

- ``msaa``: WebGL with multisampled edges (a browser's default; off otherwise);
- ``dpr=X``: ``loosefit view --pixel-ratio X`` (otherwise viser's adaptive ratio);
- ``size=WxH``: the browser's window (default 1280x800);
- ``envmap``: viser's image-based light (an environment map) on;
- ``nofloor``: the floor's grid hidden; ``floor=W``: the floor W m wide instead of
  ``loosefit.view.server.FLOOR_SIZE`` (20: to the horizon, the viewer's floor until
  2026-11-27);
- ``nobody``, ``nolabel``: the bodies, the sequences' names hidden;
- ``nobackground``: viser's background quad (drawn over the whole canvas each frame,
  discarded when no background image is set) left out by a script in the page;
- ``flag=--SWITCH``: another Chromium switch.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import dataclass, field

from loosefit.eval.process_time import cpu_seconds, descendants, gpu_process
from loosefit.sequence import GarmentSequence
from loosefit.view import ViewerConfig
from loosefit.view.headless import BODY_BYTES, Chromium
from loosefit.view.scene import from_animated
from loosefit.view.server import Viewer

NO_BACKGROUND = """setInterval(() => {
  const m = window.__viserMutable;
  if (m && m.backgroundMaterial) m.backgroundMaterial.visible = false;
}, 200);"""
# three.js's canvas: whether it is multisampled and its size in pixels
CANVAS = """(() => {
  const c = document.querySelector('canvas[data-engine]');
  const gl = c && c.getContext('webgl2');
  return gl ? [gl.getContextAttributes().antialias, gl.getParameter(gl.SAMPLES), c.width,
               c.height] : null;
})()"""


@dataclass
class Condition:
    """One trial's settings, parsed from its name (see the module's docstring)."""

    name: str
    antialias: bool = False
    pixel_ratio: float | None = None
    size: tuple[int, int] = (1280, 800)
    flags: list[str] = field(default_factory=list)
    scripts: list[str] = field(default_factory=list)
    scene: list[str] = field(default_factory=list)  # envmap, nofloor, floor=W, nobody, nolabel

    @classmethod
    def parse(cls, name: str) -> Condition:
        c = cls(name)
        for token in name.split("+"):
            key, _, value = token.partition("=")
            if token == "plain":
                pass
            elif token == "msaa":
                c.antialias = True
            elif key == "dpr":
                c.pixel_ratio = float(value)
            elif key == "size":
                c.size = tuple(int(v) for v in value.split("x"))
            elif key == "flag":
                c.flags.append(value)
            elif token == "nobackground":
                c.scripts.append(NO_BACKGROUND)
            elif token in ("envmap", "nofloor", "nobody", "nolabel") or key == "floor":
                c.scene.append(token)
            else:
                raise SystemExit(f"unknown condition {token!r} in {name!r}")
        return c

    def apply(self, viewer: Viewer) -> None:
        """The scene's changes, through the viewer's handles."""
        for token in self.scene:
            key, _, value = token.partition("=")
            if token == "envmap":
                viewer.server.scene.configure_environment_map("warehouse")
            elif token == "nofloor":
                viewer.floor.visible = False
            elif token == "nobody":
                viewer.bodies_on = False
                viewer._refresh()
            elif token == "nolabel":
                for label in viewer.labels:
                    label.visible = False
        for token in self.scene:  # last: a refresh above would size the floor again
            key, _, value = token.partition("=")
            if key == "floor":
                viewer.floor.width = viewer.floor.height = float(value)


def trial(sequences, condition: Condition, seconds: float) -> dict:
    """Serve, open, play and count under ``condition``; the figures as a dict."""
    viewer = Viewer(sequences, ViewerConfig(port=0, pixel_ratio=condition.pixel_ratio))
    try:
        condition.apply(viewer)
        width, height = condition.size
        with Chromium(
            width=width,
            height=height,
            antialias=condition.antialias,
            flags=condition.flags,
            scripts=condition.scripts,
        ) as browser:
            browser.open(viewer.url, settle=0.0)
            while not (browser.evaluate("window.__draws") or 0):
                time.sleep(0.1)
            time.sleep(3.0)  # past the first frames' set-up
            gpu = gpu_process(browser.process.pid)
            procs = descendants(browser.process.pid)
            cpu0 = [cpu_seconds(p) for p in (gpu, *procs)]
            got = browser.receive(seconds)
            cpu = [cpu_seconds(p) - c for p, c in zip((gpu, *procs), cpu0, strict=True)]
            canvas = browser.evaluate(CANVAS)
    finally:
        viewer.close()
    draws = max(got.draws, 1)
    return {
        "condition": condition.name,
        "frames_received_per_s": got.rate(BODY_BYTES),
        "drawn_per_s": got.draws / seconds,
        "new_drawn_per_s": got.new_draws / seconds,
        "gpu_ms_per_draw": 1000 * cpu[0] / draws,
        "browser_ms_per_draw": 1000 * sum(cpu[1:]) / draws,
        "browser_cores": sum(cpu[1:]) / seconds,
        "canvas": canvas,  # [multisampled, samples, width, height]
        "load": os.getloadavg()[0],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sequence", help="a sequence .npz")
    ap.add_argument("conditions", help="comma-separated conditions (module docstring)")
    ap.add_argument("--repeat", type=int, default=2, help="rounds over the conditions")
    ap.add_argument("--seconds", type=float, default=10.0, help="how long each is measured")
    ap.add_argument("--frames", type=int, default=None, help="keep the first N frames")
    ap.add_argument("--jsonl", default=None, help="also append each trial's figures here")
    args = ap.parse_args()

    conditions = [Condition.parse(name) for name in args.conditions.split(",")]
    seq = GarmentSequence.load(args.sequence)
    if args.frames:
        n = args.frames
        seq = GarmentSequence(
            seq.motion.slice(0, n), seq.garment, seq.garment_vertices[:n], seq.avatar, seq.source
        )
    sequences = from_animated([seq], [os.path.basename(args.sequence)])
    for round_ in range(args.repeat):
        for condition in conditions:
            r = trial(sequences, condition, args.seconds)
            print(
                f"{condition.name:40s} round {round_ + 1}: received "
                f"{r['frames_received_per_s']:.1f}/s, drew {r['drawn_per_s']:.1f}/s "
                f"({r['new_drawn_per_s']:.1f} new); GPU process {r['gpu_ms_per_draw']:.0f} "
                f"ms per frame drawn, all the browser's processes "
                f"{r['browser_ms_per_draw']:.0f} ms ({r['browser_cores']:.2f} of a core); "
                f"canvas {r['canvas']}; load average {r['load']:.1f}",
                flush=True,
            )
            if args.jsonl:
                with open(args.jsonl, "a") as f:
                    f.write(json.dumps(r) + "\n")


if __name__ == "__main__":
    main()
