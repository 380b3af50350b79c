"""The viewer as a browser shows it, saved as a PNG: the README's and docs/use/VIEWER.md's picture.

Serves sequences in ``loosefit.view`` and screenshots the page in headless Chromium (SwiftShader
WebGL) at one frame, the camera following the bodies::

    .venv/bin/python bench/quality/viewer_screenshot.py out/dance1957_rigid.npz out/dance1957.npz \\
        --names rigid,"loosefit model" --frames 400 --frame 250 --colour error --scale 20 \\
        --antialias --out docs/img/viewer.png
"""

from __future__ import annotations

import argparse

from PIL import Image

from loosefit.sequence import GarmentSequence
from loosefit.view import ViewerConfig, view
from loosefit.view.headless import Chromium


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sequences", nargs="+", help="sequence .npz files of one garment and motion")
    ap.add_argument("--names", default=None, help="comma-separated labels")
    ap.add_argument("--frames", type=int, default=None, help="keep the first N frames")
    ap.add_argument("--frame", type=int, default=0, help="the frame shown")
    ap.add_argument("--colour", default="plain", help="plain, error, strain or inside")
    ap.add_argument("--scale", type=float, default=None, help="the colour bar's top, its unit")
    ap.add_argument("--size", default="1200x860", help="the browser's window")
    ap.add_argument("--colours", type=int, default=256, help="palette size of the PNG")
    ap.add_argument("--pixel-ratio", type=float, default=None, help="view --pixel-ratio")
    ap.add_argument(
        "--antialias",
        action="store_true",
        help="multisampled edges (a browser's default; the docs' picture)",
    )
    ap.add_argument("--out", required=True)
    args = ap.parse_args()

    seqs = [GarmentSequence.load(p) for p in args.sequences]
    if args.frames:
        n = args.frames
        seqs = [
            GarmentSequence(
                s.motion.slice(0, n), s.garment, s.garment_vertices[:n], s.avatar, s.source
            )
            for s in seqs
        ]
    names = args.names.split(",") if args.names else None
    config = ViewerConfig(port=0, play=False, colouring=args.colour, pixel_ratio=args.pixel_ratio)
    viewer = view(seqs, names, config)
    try:
        if args.scale is not None:
            viewer.scale_max.value = args.scale
        width, height = (int(v) for v in args.size.split("x"))
        with Chromium(width=width, height=height, antialias=args.antialias) as browser:
            browser.open(viewer.url, settle=3.0, panel=viewer.panel_labels)  # all controls
            first = browser.settled_screenshot()
            viewer.set_frame(args.frame)
            shot = browser.settled_screenshot(first if args.frame else None)
        image = Image.fromarray(shot)
        if args.colours < 256:
            image = image.quantize(args.colours)
        image.save(args.out, optimize=True)
        print(f"wrote {args.out}")
    finally:
        viewer.close()


if __name__ == "__main__":
    main()
