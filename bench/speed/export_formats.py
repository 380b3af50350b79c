"""Every export format of a sequence: seconds to write, size, and what Blender sees.

For a sequence (``make demo``'s ``out/demo/sequence.npz``), writes USD with the body
skinned and as points, Alembic and glTF; times each (the body posed beforehand, once),
opens each in Blender (``bpy``, through ``loosefit/export/blender_read.py``) and measures
the largest distance between Blender's vertices and loosefit's at three frames, renders
one frame of each to ``--png-dir``, and with ``--long N`` measures the peak memory of
writing an N-frame garment in each format (a child process each) against the sequence's
own size. Prints a Markdown table; ``--out`` writes it.

    python bench/speed/export_formats.py out/demo/sequence.npz --png-dir docs/img --long 10000
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import loosefit.export
from loosefit.export import ExportConfig, export_animation, garment_and_body
from loosefit.export.gltf import split_uvs
from loosefit.sequence import GarmentSequence

READER = Path(loosefit.export.__file__).with_name("blender_read.py")
FORMATS = {  # label: (file name, config)
    "USD, body skinned": ("demo.usdc", ExportConfig()),
    "USD, body as points": ("points.usdc", ExportConfig(skinned_body=False)),
    "Alembic": ("demo.abc", ExportConfig()),
    "glTF": ("demo.glb", ExportConfig()),
}


def blender_errors(path: Path, meshes, fps: float, frames: list[int], png: Path | None):
    """The largest distance (mm) per mesh between Blender's vertices and ``meshes``."""
    out = path.with_suffix(path.suffix + ".npz")
    cmd = [
        sys.executable,
        str(READER),
        str(path),
        "--fps",
        str(fps),
        "--out",
        str(out),
        "--frames",
        *map(str, frames),
    ]
    if png is not None:
        cmd += ["--png", str(png), "--png-frame", str(frames[1])]
    subprocess.run(cmd, check=True, capture_output=True)
    seen = np.load(out)
    errors = {}
    for m in meshes:
        source = split_uvs(m)[0] if path.suffix == ".glb" else slice(None)
        got = seen[m.name]
        errors[m.name] = float(np.linalg.norm(got - m.vertices[frames][:, source], axis=-1).max())
    return {k: v * 1e3 for k, v in errors.items()}


def long_memory(frames: int, fmt: str, folder: Path) -> str:
    """Child process: peak resident memory of writing a ``frames``-long garment in ``fmt``."""
    code = f"""
import numpy as np
from pathlib import Path
from loosefit.export import AnimatedMesh, export_animation
from tests.meshes import grid
v, f = grid(49, -0.3, 0.3, 1.0)  # 2,401 vertices, about the skirt's
rng = np.random.default_rng(0)
g = np.empty(({frames}, len(v), 3), np.float32)
for s in range(0, {frames}, 100):  # in small pieces: no temporary sets the peak before
    n = len(g[s : s + 100])
    g[s : s + n] = v + 0.01 * rng.standard_normal((n, len(v), 3), np.float32)
def hwm():  # this process's peak resident kB (ru_maxrss would count the parent's before exec)
    return int(next(x for x in open('/proc/self/status') if x.startswith('VmHWM')).split()[1])
before = hwm()
garment = AnimatedMesh('garment', f, g, normals=True)
export_animation(Path('{folder}') / 'long{fmt}', [garment], 30.0)
print(g.nbytes / 2**20, (hwm() - before) / 1024)
"""
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    data, extra = map(float, run.stdout.split()[-2:])
    return f"{fmt}: sequence {data:.0f} MiB, peak memory beyond it {extra:.0f} MiB"


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("sequence")
    p.add_argument("--png-dir", default=None)
    p.add_argument("--long", type=int, default=0, help="frames of the memory check (0: none)")
    p.add_argument("--out", default=None)
    args = p.parse_args()

    seq = GarmentSequence.load(args.sequence)
    t0 = time.perf_counter()
    body, faces, skin = seq.body_vertices, seq.body_faces, seq.body_skin
    pose_s = time.perf_counter() - t0
    meshes = garment_and_body(seq.garment, seq.garment_vertices, body, faces, skin)
    T = seq.num_frames
    frames = [0, T // 2, T - 1]
    lines = [
        f"Sequence `{Path(args.sequence).name}`: {T} frames at {seq.fps:g} fps, garment "
        f"{seq.garment_vertices.shape[1]} vertices, body {body.shape[1]}; posing the body "
        f"and its rig {pose_s:.1f} s (once, before the exports). Rig against the posed body: "
        f"{skin.error(body) * 1e3:.4f} mm at most.",
        "",
        "| format | file | write (s) | size (MB) | Blender: garment error (mm) | body (mm) |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    with tempfile.TemporaryDirectory() as tmp:
        for label, (name, config) in FORMATS.items():
            path = Path(tmp) / name
            t0 = time.perf_counter()
            export_animation(path, meshes, seq.fps, config)
            seconds = time.perf_counter() - t0
            png = None
            if args.png_dir:
                png = Path(args.png_dir) / f"export_{path.stem}_{path.suffix[1:]}.png"
            err = blender_errors(path, meshes, seq.fps, frames, png)
            lines.append(
                f"| {label} | `{name}` | {seconds:.1f} | {path.stat().st_size / 1e6:.1f} | "
                f"{err['garment']:.4f} | {err['body']:.4f} |"
            )
            print(lines[-1], flush=True)
        if args.long:
            lines.append("")
            lines.append(f"Writing a {args.long}-frame garment (a child process each):")
            for fmt in (".usdc", ".abc", ".glb"):
                lines.append(f"- {long_memory(args.long, fmt, Path(tmp))}")
                print(lines[-1], flush=True)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    lines.append(f"\nThis process's peak memory: {peak:.0f} MiB.")
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        Path(args.out).write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
