"""Time the offscreen renderer on a body-sized synthetic scene.

A ~14k-vertex capsule "body" swaying and travelling, and a ~10k-vertex cone
"skirt" rippling around it, rendered at 640x640 per view with the default
RenderConfig (4x MSAA, 2048 px shadow map, floor, labels), 1 and 3 views.

Run:  PYTHONPATH=src python bench/speed/render_speed.py [--frames 20] [--size 640]
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

from loosefit.render.geometry import capsule, open_cone
from loosefit.render.renderer import RenderConfig, Renderer, RenderMesh


def synthetic_scene(frames: int) -> list[RenderMesh]:
    """Body (~14k vertices) and skirt (~10k vertices) animated over ``frames`` frames."""
    body_v, body_f = capsule(radius=0.16, height=1.7, segments=128, rings=110)
    skirt_v, skirt_f = open_cone(0.19, 0.5, 1.0, 0.4, segments=100, rings=100)
    t = np.arange(frames, dtype=np.float32)[:, None] / 30.0  # (T, 1) seconds
    shift = np.stack([0.3 * t[:, 0], 0.1 * np.sin(4 * t[:, 0]), 0 * t[:, 0]], -1)  # (T, 3)
    body = body_v[None] + shift[:, None]  # (T, Vb, 3)
    body[..., 0] += 0.05 * np.sin(3 * t) * body_v[None, :, 2]  # sway
    angle = np.arctan2(skirt_v[:, 1], skirt_v[:, 0])  # (V,)
    drop = (1.0 - skirt_v[:, 2]) / 0.6  # 0 at the waist, 1 at the hem
    ripple = 1.0 + 0.15 * drop * np.sin(6 * angle[None] + 8 * t)  # (T, V)
    skirt = skirt_v[None].repeat(frames, 0)  # (T, V, 3)
    skirt[..., :2] *= ripple[..., None]
    skirt += shift[:, None]
    return [
        RenderMesh(body_f, body, role="body", name="body"),
        RenderMesh(skirt_f, skirt, role="garment", name="skirt"),
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=20)
    parser.add_argument("--size", type=int, default=640)
    args = parser.parse_args()
    scene = synthetic_scene(args.frames)
    print(
        f"machine: {platform.platform()}, {platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} CPUs, python {platform.python_version()}"
    )
    print(
        f"scene: body {scene[0].num_vertices} verts / {len(scene[0].faces)} faces, "
        f"skirt {scene[1].num_vertices} verts / {len(scene[1].faces)} faces, {args.frames} frames"
    )
    cases = [
        (("front",), 4),
        (("front", "side", "three_quarter"), 4),
        (("front",), 0),  # without MSAA, for the trade-off
    ]
    for views, msaa in cases:
        config = RenderConfig(
            width=args.size, height=args.size, views=views, msaa=msaa, follow=True
        )
        with Renderer(config) as renderer:
            if views == ("front",) and msaa:
                info = renderer.ctx.info
                print(f"OpenGL: {info['GL_RENDERER']} / {info['GL_VERSION']}")
            next(iter(renderer.render_sequence(scene, frames=[0])))  # warm up (shader compile)
            wall, cpu = [], []
            frames = iter(renderer.render_sequence(scene))
            for _ in range(args.frames):
                w, c = time.perf_counter(), time.process_time()
                next(frames)
                wall.append(time.perf_counter() - w)
                cpu.append(time.process_time() - c)  # all threads, including llvmpipe's
        w, c = float(np.median(wall)), float(np.median(cpu))
        print(
            f"{len(views)} view(s) {args.size}x{args.size} msaa {msaa}: "
            f"{w:.3f} s/frame wall ({w / len(views):.3f} s/view), {c:.3f} s/frame CPU (median)"
        )


if __name__ == "__main__":
    main()
