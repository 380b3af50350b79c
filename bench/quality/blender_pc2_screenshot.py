"""A PC2 + OBJ export opened in Blender as a user opens it: what Blender shows, and a picture.

For a sequence (``make demo``'s ``out/demo/sequence.npz``), writes the garment and the body
as PC2 + OBJ (``demo.pc2``, ``demo.obj``, ``demo_body.pc2``, ``demo_body.obj``; Y up unless
``--up-axis Z``), opens them in Blender (``bpy``, through
``loosefit/export/blender_read.py``): each OBJ imported with the importer's defaults and a
Mesh Cache modifier on it reading its PC2 (format PC2, every other setting at its default).
Measures the largest distance between Blender's world vertices and loosefit's at the first,
middle and last frames, and renders the middle frame with Workbench, the camera on the
skirt, to ``--png``. Prints a Markdown line.

    python bench/quality/blender_pc2_screenshot.py out/demo/sequence.npz \\
        --png docs/img/export_demo_pc2.png
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import loosefit.export
from loosefit.export import ExportConfig, export_animation, garment_and_body
from loosefit.sequence import GarmentSequence

READER = Path(loosefit.export.__file__).with_name("blender_read.py")


def blender_sees(files: list[Path], meshes, fps: float, frames: list[int], png: list[str]):
    """The largest distance (mm) per mesh between Blender's world vertices and ``meshes``
    at ``frames``, the files opened in one scene (``png``: the picture's arguments)."""
    out = files[0].with_suffix(".seen.npz")
    cmd = [
        sys.executable,
        str(READER),
        *map(str, files),
        "--fps",
        str(fps),
        "--out",
        str(out),
        "--frames",
        *map(str, frames),
        *png,
    ]
    subprocess.run(cmd, check=True, capture_output=True)
    seen = np.load(out)
    return {
        m.name: 1e3 * float(np.linalg.norm(seen[m.name] - m.vertices[frames], axis=-1).max())
        for m in meshes
    }


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("sequence")
    p.add_argument("--png", default=None, help="the picture (default: none)")
    p.add_argument("--frame", type=int, default=None, help="the frame drawn (default: middle)")
    p.add_argument("--up-axis", choices=("Y", "Z"), default=None, help="the export's axes")
    p.add_argument("--distance", type=float, default=1.6, help="the camera's distance, x")
    args = p.parse_args()

    seq = GarmentSequence.load(args.sequence)
    meshes = garment_and_body(
        seq.garment, seq.garment_vertices, seq.body_vertices, seq.body_faces, seq.body_skin
    )
    T = seq.num_frames
    frames = [0, T // 2, T - 1]
    drawn = T // 2 if args.frame is None else args.frame
    config = ExportConfig(up_axis=args.up_axis)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "demo.pc2"
        t0 = time.perf_counter()
        written = export_animation(path, meshes, seq.fps, config)
        seconds = time.perf_counter() - t0
        size = sum(f.stat().st_size for f in written) / 1e6
        err = blender_sees([path], meshes, seq.fps, frames, [])
        rows.append(
            f"| garment and body: `demo.pc2` + `demo.obj`, `demo_body.pc2` + `demo_body.obj`, "
            f"{args.up_axis or 'Y'} up | {seconds:.1f} | {size:.1f} | {err['garment']:.4f} | "
            f"{err['body']:.4f} |"
        )
        if args.png:  # the skirt from its PC2, the body from a USD beside it
            skirt, body = Path(tmp) / "skirt.pc2", Path(tmp) / "body.usdc"
            export_animation(skirt, meshes[:1], seq.fps, config)
            export_animation(body, meshes[1:], seq.fps)
            png = [
                "--png",
                str(Path(args.png).resolve()),
                "--png-frame",
                str(drawn),
                "--png-on",
                "garment",
                "--png-distance",
                str(args.distance),
            ]
            err = blender_sees([skirt, body], meshes, seq.fps, frames, png)
            rows.append(
                f"| the picture: `skirt.pc2` + `skirt.obj`, the body from `body.usdc` | | | "
                f"{err['garment']:.4f} | {err['body']:.4f} |"
            )
    print(
        f"Sequence `{Path(args.sequence).name}`: {T} frames at {seq.fps:g} fps; Blender's "
        f"vertices compared at frames {frames}" + (f", frame {drawn} drawn." if args.png else ".")
    )
    print("| opened in Blender | write (s) | size (MB) | garment error (mm) | body (mm) |")
    print("| --- | --- | --- | --- | --- |")
    print("\n".join(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
