"""Headless Chromium, driven over the DevTools protocol: screenshots of the viewer and the
rate at which a browser receives and draws its frames.

For the viewer's tests, its benchmark (``bench/speed/viewer_fps.py``) and the docs' screenshots;
nothing here is needed to use the viewer. Chromium draws WebGL without a GPU or a display
with SwiftShader (``--use-angle=swiftshader``), by default without multisampled edges
(:data:`NO_ANTIALIAS`: half a frame's cost there). The protocol is spoken over the
``websockets`` library that viser brings.
"""

from __future__ import annotations

import base64
import io
import itertools
import json
import shutil
import subprocess
import tempfile
import time
import urllib.request
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

BODY_BYTES = 12 * 13718  # the avatar's vertices, float32: a frame's upload is at least this
BINARIES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--use-angle=swiftshader",  # WebGL on the CPU
    "--enable-unsafe-swiftshader",
    "--disable-background-timer-throttling",
    "--disable-renderer-backgrounding",
    "--remote-debugging-port=0",  # a free port, written to DevToolsActivePort
)
# WebGL without multisampling: in software (SwiftShader) a 4-sample canvas costs about twice
# as much per frame drawn as a plain one (docs/use/VIEWER.md); what is lost is smooth edges.
NO_ANTIALIAS = ("--webgl-antialiasing-mode=none",)
# Counts in the page (1) the frames it draws: three.js clears the canvas once per frame,
# (2) those of them that followed the arrival of a frame's message (vertices at least a
# body's size; the rest redrew the frame already shown), and (3) the messages it receives:
# viser's websocket lives in a web worker, which hands the page each batch of decoded
# messages; the arrival times and the bytes of their arrays (vertices, faces) are kept.
INSTRUMENT = """
(() => {
  window.__draws = 0;
  window.__newDraws = 0;
  window.__received = [];
  let fresh = false;  // a frame arrived since the last draw
  for (const C of [WebGLRenderingContext, WebGL2RenderingContext]) {
    const clear = C.prototype.clear;
    C.prototype.clear = function (mask) {
      if (mask & this.COLOR_BUFFER_BIT) {
        window.__draws += 1;
        if (fresh) window.__newDraws += 1;
        fresh = false;
      }
      return clear.call(this, mask);
    };
  }
  const Base = window.Worker;
  window.Worker = function (...args) {
    const worker = new Base(...args);
    const bytes = (x, depth) => {
      if (ArrayBuffer.isView(x)) return x.byteLength;
      if (depth > 4 || x === null || typeof x !== "object") return 0;
      let n = 0;
      for (const k in x) n += bytes(x[k], depth + 1);
      return n;
    };
    worker.addEventListener("message", (e) => {
      if (e.data && Array.isArray(e.data.messages)) {
        const n = bytes(e.data.messages, 0);
        window.__received.push([performance.now(), n]);
        if (n >= BODY_BYTES) fresh = true;
      }
    });
    return worker;
  };
  window.Worker.prototype = Base.prototype;
})();
""".replace("BODY_BYTES", str(BODY_BYTES))
# Viser's control panel in the page (its floating window; below 576 px wide viser shows a
# sheet at the bottom instead, which carries no such mark: then the whole page is searched).
PANEL = '[data-testid="floating-panel"]'
# Viser's notice that WebGL runs in software (true here) would cover part of the view.
HIDE_NOTICES = (
    "const s = document.createElement('style');"
    "s.textContent = '.mantine-Notifications-root {display: none !important}';"
    "document.head.appendChild(s);"
)


def find_chromium() -> str | None:
    """The path of a Chromium or Chrome binary on PATH, or None."""
    for name in BINARIES:
        path = shutil.which(name)
        if path:
            return path
    return None


def command(
    binary: str,
    profile: Path,
    width: int,
    height: int,
    antialias: bool = False,
    flags: Sequence[str] = (),
) -> list[str]:
    """The command line of a headless Chromium (:class:`Chromium`'s arguments)."""
    size = f"--window-size={width},{height}"
    quality = () if antialias else NO_ANTIALIAS
    return [binary, *FLAGS, *quality, *flags, f"--user-data-dir={profile}", size, "about:blank"]


@dataclass
class Received:
    """What a page received and drew over a measurement.

    Attributes:
        seconds: how long it was measured.
        messages: (N,) the sizes in bytes of the websocket messages the page received.
        times: (N,) s, when each reached the page (the browser's clock).
        draws: frames the page drew in that time (WebGL clears of the canvas).
        new_draws: those of ``draws`` that followed the arrival of a frame (the rest redrew
            the frame already shown): at most one per frame received.
    """

    seconds: float
    messages: np.ndarray
    times: np.ndarray
    draws: int
    new_draws: int

    def rate(self, min_bytes: int = 0) -> float:
        """Messages of at least ``min_bytes`` per second, between the first and the last."""
        t = self.times[self.messages >= min_bytes]
        return (len(t) - 1) / (t[-1] - t[0]) if len(t) > 1 and t[-1] > t[0] else 0.0


class Chromium:
    """A headless Chromium with one page, driven over the DevTools protocol.

    Args:
        binary: the browser (default: :func:`find_chromium`).
        width, height: the window in pixels.
        timeout: s to wait for the browser to start and for each command.
        antialias: WebGL's multisampled edges, as a browser gives them by default; off
            (:data:`NO_ANTIALIAS`), a frame costs SwiftShader about half as much.
        flags: command-line switches added to :data:`FLAGS` (a later one wins).
        scripts: JavaScript run in every page before its own (after the counters').
    """

    def __init__(
        self,
        binary: str | None = None,
        *,
        width: int = 1280,
        height: int = 800,
        timeout: float = 60.0,
        antialias: bool = False,
        flags: Sequence[str] = (),
        scripts: Sequence[str] = (),
    ) -> None:
        from websockets.sync.client import connect

        binary = binary or find_chromium()
        if binary is None:
            raise FileNotFoundError(f"no Chromium: none of {BINARIES} on PATH")
        self.timeout = timeout
        # the browser's helpers may still write there as it quits: cleaned up as they can be
        self._profile = tempfile.TemporaryDirectory(
            prefix="loosefit-chromium-", ignore_cleanup_errors=True
        )
        profile = Path(self._profile.name)
        self.process = subprocess.Popen(
            command(binary, profile, width, height, antialias, flags),
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        port_file = profile / "DevToolsActivePort"
        deadline = time.monotonic() + timeout
        while not (port_file.is_file() and port_file.read_text().strip()):
            if self.process.poll() is not None or time.monotonic() > deadline:
                self.close()
                raise RuntimeError(f"{binary} did not start (exit {self.process.poll()})")
            time.sleep(0.1)
        port = int(port_file.read_text().split()[0])
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=10) as r:
            pages = [t for t in json.load(r) if t.get("type") == "page"]
        self._ws = connect(pages[0]["webSocketDebuggerUrl"], max_size=None, open_timeout=timeout)
        self._ids = itertools.count(1)
        self._events: list[dict] = []
        self.call("Page.enable")
        for source in (INSTRUMENT, *scripts):
            self.call("Page.addScriptToEvaluateOnNewDocument", source=source)

    def call(self, method: str, **params) -> dict:
        """Send one command and return its result (events meanwhile are kept)."""
        i = next(self._ids)
        self._ws.send(json.dumps({"id": i, "method": method, "params": params}))
        deadline = time.monotonic() + self.timeout
        while True:
            msg = json.loads(self._ws.recv(timeout=max(deadline - time.monotonic(), 0.01)))
            if msg.get("id") == i:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})
            self._events.append(msg)

    def evaluate(self, expression: str):
        """The value of a JavaScript expression in the page."""
        result = self.call("Runtime.evaluate", expression=expression, returnByValue=True)
        return result.get("result", {}).get("value")

    def open(self, url: str, settle: float = 2.0, panel: Sequence[str] = ()) -> None:
        """Load ``url`` and wait until it has loaded, its panel shows every label of
        ``panel`` (:meth:`wait_for_panel`; a viewer's :attr:`~loosefit.view.server.Viewer.
        panel_labels`) and ``settle`` seconds more."""
        self._events.clear()
        self.call("Page.navigate", url=url)
        self._wait_event("Page.loadEventFired")
        self.evaluate(HIDE_NOTICES)
        if panel:
            self.wait_for_panel(panel)
        time.sleep(settle)

    def panel_missing(self, labels: Sequence[str]) -> list[str] | None:
        """Those of ``labels`` not (yet) in the page's control panel (:data:`PANEL`, or the
        whole page where there is none); None before the page has a body."""
        script = (
            f"(() => {{ const root = document.querySelector({json.dumps(PANEL)}) || document.body;"
            " if (!root) return null; const text = root.textContent;"
            f" return {json.dumps(list(labels))}.filter((s) => !text.includes(s)); }})()"
        )
        return self.evaluate(script)

    def wait_for_panel(self, labels: Sequence[str], timeout: float | None = None) -> float:
        """Wait until the page's control panel holds every one of ``labels`` (the page
        loads at once; its panel arrives over the websocket after, control by control, and
        a screenshot before then shows it empty or half built).

        Returns:
            The seconds waited.

        Raises:
            TimeoutError: naming the labels still missing after ``timeout`` s (default:
                the browser's).
        """
        start = time.monotonic()
        timeout = self.timeout if timeout is None else timeout
        while True:
            missing = self.panel_missing(labels)
            if missing == []:
                return time.monotonic() - start
            if time.monotonic() - start > timeout:
                lacks = list(labels) if missing is None else missing
                raise TimeoutError(f"the viewer's panel still lacks {lacks} after {timeout:g} s")
            time.sleep(0.1)

    def _wait_event(self, method: str) -> dict:
        deadline = time.monotonic() + self.timeout
        while time.monotonic() < deadline:
            for e in self._events:
                if e.get("method") == method:
                    return e
            try:
                self._events.append(json.loads(self._ws.recv(timeout=0.5)))
            except TimeoutError:
                pass
        raise TimeoutError(f"no {method} in {self.timeout} s")

    def screenshot(self) -> np.ndarray:
        """(H, W, 3) uint8 the page as it is drawn now."""
        from PIL import Image

        data = base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])
        return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))

    def settled_screenshot(
        self, before: np.ndarray | None = None, timeout: float = 30.0, pause: float = 0.5
    ) -> np.ndarray:
        """A screenshot once the page has changed from ``before`` (if given) and then holds
        still between two screenshots ``pause`` apart (the browser has drawn an update)."""
        deadline = time.monotonic() + timeout
        last = self.screenshot()
        while time.monotonic() < deadline:
            time.sleep(pause)
            shot = self.screenshot()
            changed = before is None or not np.array_equal(shot, before)
            if changed and np.array_equal(shot, last):
                return shot
            last = shot
        return last

    def receive(self, seconds: float) -> Received:
        """Count for ``seconds`` the messages the page receives and the frames it draws."""
        count = "[window.__draws, window.__newDraws]"
        self.evaluate("window.__received = []")
        draws0, new0 = self.evaluate(count)
        time.sleep(seconds)
        draws, new = self.evaluate(count)
        got = np.array(self.evaluate("window.__received") or [], np.float64).reshape(-1, 2)
        return Received(
            seconds,
            got[:, 1].astype(np.int64),
            got[:, 0] / 1000.0,
            int(draws - draws0),
            int(new - new0),
        )

    def close(self) -> None:
        """Quit the browser and remove its profile."""
        ws = getattr(self, "_ws", None)
        if ws is not None:
            ws.close()
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        for _ in range(10):  # the helper processes leave shortly after the browser
            self._profile.cleanup()
            if not Path(self._profile.name).exists():
                break
            time.sleep(0.2)

    def __enter__(self) -> Chromium:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
