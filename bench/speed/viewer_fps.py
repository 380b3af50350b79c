"""How fast the viewer opens a long sequence and how fast a browser gets its frames.

Runs ``loosefit view`` on the sequences in a process of its own (timed from the start to
the printed URL: read, bodies posed, server up), opens the page in headless Chromium
(SwiftShader WebGL: no GPU, no display), lets it play, and counts in the browser for
``--seconds`` (1) the message batches that carry a frame (arrays at least as large as the
body's vertices) as they reach the page's script (viser's websocket worker decodes them
and hands them over), (2) the frames the page drew (its WebGL canvas cleared), and (3) the
CPU time of Chromium's GPU process (where SwiftShader draws) per frame drawn: what a frame
costs, less sensitive than the rate to other jobs sharing the machine; and that of all the
browser's processes and of the server. Of the frames drawn it also counts those that
followed a new frame's arrival (the rest redrew the frame shown). Chromium draws without
multisampling unless ``--antialias`` (``loosefit.view.headless.NO_ANTIALIAS``).
docs/use/VIEWER.md quotes its output::

    .venv/bin/python bench/speed/viewer_fps.py out/dance1957.npz
    .venv/bin/python bench/speed/viewer_fps.py out/dance1957.npz out/dance1957_rigid.npz \\
        --seconds 20
    .venv/bin/python bench/speed/viewer_fps.py out/dance1957.npz --pixel-ratio 0.5 --antialias
    .venv/bin/python bench/speed/viewer_fps.py out/dance1957.npz --flag=--num-raster-threads=1
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import time

import numpy as np

from loosefit.eval.process_time import cpu_seconds, descendants, gpu_process
from loosefit.sequence import GarmentSequence
from loosefit.view.headless import BODY_BYTES, Chromium


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sequences", nargs="+", help="sequence .npz files of one garment and motion")
    ap.add_argument("--seconds", type=float, default=15.0, help="how long to measure")
    ap.add_argument("--colour", default="plain", help="the viewer's colouring (view --colour)")
    ap.add_argument("--port", type=int, default=8090)
    ap.add_argument("--size", default="1280x800", help="the browser's window")
    ap.add_argument("--pixel-ratio", type=float, default=None, help="view --pixel-ratio")
    ap.add_argument(
        "--antialias",
        action="store_true",
        help="WebGL with multisampled edges (a browser's default)",
    )
    ap.add_argument(
        "--flag",
        action="append",
        default=[],
        help="another Chromium switch (repeatable), e.g. --flag=--num-raster-threads=1",
    )
    args = ap.parse_args()

    seq = GarmentSequence.load(args.sequences[0])
    T, V = seq.garment_vertices.shape[:2]
    cmd = [
        sys.executable,
        "-m",
        "loosefit.cli",
        "view",
        *args.sequences,
        "--port",
        str(args.port),
        "--colour",
        args.colour,
    ]
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
        print(
            f"{len(args.sequences)} sequence(s) of {T} frames at {seq.fps:g} fps, garment "
            f"{V} vertices: loosefit view printed its URL {time.perf_counter() - t0:.1f} s "
            "after it started (Python's start, reading, posing the bodies, serving)"
        )
        width, height = (int(v) for v in args.size.split("x"))
        with Chromium(
            width=width, height=height, antialias=args.antialias, flags=args.flag
        ) as browser:
            t1 = time.perf_counter()
            browser.open(url, settle=0.0)
            while not (browser.evaluate("window.__draws") or 0):
                time.sleep(0.1)
            print(
                f"page loaded and drawing {time.perf_counter() - t1:.1f} s after Chromium started"
            )
            time.sleep(3.0)  # past the first frames' set-up
            gpu = gpu_process(browser.process.pid)
            procs = descendants(browser.process.pid)
            cpu0 = [cpu_seconds(p) for p in (gpu, *procs, server.pid)]
            got = browser.receive(args.seconds)
            cpu = [cpu_seconds(p) - c for p, c in zip((gpu, *procs, server.pid), cpu0, strict=True)]
            gpu_cpu, browser_cpu, server_cpu = cpu[0], sum(cpu[1:-1]), cpu[-1]
        big = got.messages >= BODY_BYTES
        gaps = np.diff(got.times[big]) * 1000.0 if big.sum() > 1 else np.zeros(1)
        print(
            f"in {args.seconds:g} s the browser received {int(big.sum())} frame messages "
            f"({got.rate(BODY_BYTES):.1f} per second; {got.messages[big].mean() / 1e3:.0f} kB "
            f"each; gaps median {np.median(gaps):.1f} ms, 95th percentile "
            f"{np.percentile(gaps, 95):.1f} ms) and drew {got.draws} frames "
            f"({got.draws / args.seconds:.1f} per second, {got.new_draws / args.seconds:.1f} "
            f"of them a new frame; the GPU process used {gpu_cpu / args.seconds:.2f} of a "
            f"core, {1000 * gpu_cpu / max(got.draws, 1):.0f} ms per frame drawn; all the "
            f"browser's processes {browser_cpu / args.seconds:.2f}, "
            f"{1000 * browser_cpu / max(got.draws, 1):.0f} ms; the server "
            f"{server_cpu / args.seconds:.2f}; load average "
            f"{os.getloadavg()[0]:.1f})"
        )
    finally:
        server.terminate()
        server.wait(timeout=30)


if __name__ == "__main__":
    main()
