"""How fast the viewer opens a long sequence and how fast a browser gets its frames (issue 38).

Runs ``loosefit view`` on the sequences in a process of its own (timed from the start to
the printed URL: read, bodies posed, server up), opens the page in headless Chromium
(SwiftShader WebGL: no GPU, no display), lets it play, and counts in the browser for
``--seconds`` (1) the message batches that carry a frame (arrays at least as large as the
body's vertices) as they reach the page's script (viser's websocket worker decodes them
and hands them over), (2) the frames the page drew (its WebGL canvas cleared), and (3) the
CPU time of Chromium's GPU process (where SwiftShader draws) per frame drawn: what a frame
costs, less sensitive than the rate to other jobs sharing the machine.
docs/VIEWER.md quotes its output::

    .venv/bin/python bench/viewer_fps.py out/dance1957.npz
    .venv/bin/python bench/viewer_fps.py out/dance1957.npz out/dance1957_rigid.npz --seconds 20
    .venv/bin/python bench/viewer_fps.py out/dance1957.npz --pixel-ratio 0.5
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from loosefit.sequence import AnimatedGarment
from loosefit.view.headless import Chromium


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sequences", nargs="+", help="sequence .npz files of one garment and motion")
    ap.add_argument("--seconds", type=float, default=15.0, help="how long to measure")
    ap.add_argument("--colour", default="plain", help="the viewer's colouring (view --colour)")
    ap.add_argument("--port", type=int, default=8090)
    ap.add_argument("--size", default="1280x800", help="the browser's window")
    ap.add_argument("--pixel-ratio", type=float, default=None, help="view --pixel-ratio")
    args = ap.parse_args()

    seq = AnimatedGarment.load(args.sequences[0])
    T, V = seq.garment_vertices.shape[:2]
    cmd = [sys.executable, "-m", "loosefit.cli", "view", *args.sequences, "--port",
           str(args.port), "--colour", args.colour]  # fmt: skip
    if args.pixel_ratio is not None:
        cmd += ["--pixel-ratio", str(args.pixel_ratio)]
    env = dict(os.environ, OMP_NUM_THREADS=os.environ.get("OMP_NUM_THREADS", "1"))
    t0 = time.perf_counter()
    server = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True, env=env)
    try:
        url = None
        for line in server.stdout:
            m = re.search(r"loosefit viewer: (http://\S+)", line)
            if m:
                url = m.group(1)
                break
        if url is None:
            raise SystemExit(f"loosefit view exited ({server.wait()}) without a URL")
        print(f"{len(args.sequences)} sequence(s) of {T} frames at {seq.fps:g} fps, garment "
              f"{V} vertices: loosefit view printed its URL {time.perf_counter() - t0:.1f} s "
              "after it started (Python's start, reading, posing the bodies, serving)")  # fmt: skip
        width, height = (int(v) for v in args.size.split("x"))
        with Chromium(width=width, height=height) as browser:
            t1 = time.perf_counter()
            browser.open(url, settle=0.0)
            while not (browser.evaluate("window.__draws") or 0):
                time.sleep(0.1)
            print(f"page loaded and drawing {time.perf_counter() - t1:.1f} s after Chromium "
                  "started")  # fmt: skip
            time.sleep(3.0)  # past the first frames' set-up
            gpu = _gpu_process(browser.process.pid)
            cpu0 = _cpu_seconds(gpu)
            got = browser.receive(args.seconds)
            gpu_cpu = _cpu_seconds(gpu) - cpu0
        body_bytes = 12 * 13718  # the avatar's vertices, float32
        big = got.messages >= body_bytes
        gaps = np.diff(got.times[big]) * 1000.0 if big.sum() > 1 else np.zeros(1)
        print(f"in {args.seconds:g} s the browser received {int(big.sum())} frame messages "
              f"({got.rate(body_bytes):.1f} per second; {got.messages[big].mean() / 1e3:.0f} kB "
              f"each; gaps median {np.median(gaps):.1f} ms, 95th percentile "
              f"{np.percentile(gaps, 95):.1f} ms) and drew {got.draws} frames "
              f"({got.draws / args.seconds:.1f} per second; the GPU process used "
              f"{gpu_cpu / args.seconds:.2f} of a core, {1000 * gpu_cpu / max(got.draws, 1):.0f} "
              f"ms per frame drawn; load average {os.getloadavg()[0]:.1f})")  # fmt: skip
    finally:
        server.terminate()
        server.wait(timeout=30)


def _gpu_process(pid: int) -> int | None:
    """The id of Chromium's GPU process (``--type=gpu-process``) among the descendants of
    ``pid`` (the launcher may be a script), read from Linux's /proc; None when none is."""
    parent, gpu = {}, []
    for proc in Path("/proc").glob("[0-9]*"):
        try:
            cmdline = (proc / "cmdline").read_bytes()  # Chromium rewrites it: one string
            parent[int(proc.name)] = int((proc / "stat").read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, ValueError, IndexError):
            continue
        if b"--type=gpu-process" in cmdline:
            gpu.append(int(proc.name))
    for candidate in gpu:
        p = candidate
        while p in parent and p != pid:
            p = parent[p]
        if p == pid:
            return candidate
    return None


def _cpu_seconds(pid: int | None) -> float:
    """User and system CPU seconds of a process so far (0 when there is none)."""
    if pid is None:
        return 0.0
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


if __name__ == "__main__":
    main()
