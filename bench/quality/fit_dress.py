"""A dress made for another body, fitted (``garment --fit``) and simulated through a 4 s clip:
its target at full resolution (tests/fitting/test_drape.py's slow test is the coarse version).

The parametric strapless dress (the ``cpu`` preset, 2,312 vertices) is made for a markedly
different anny body (heavier, taller, other proportions), written in centimetres with Y up as
another tool would, imported with ``--fit`` onto the project's avatar and simulated through a
4 s procedural dance (120 frames at 30 fps) with the data sets' cloth (``ClothConfig``, the
upper arms colliding). It prints the fit's displacements, the deepest garment vertex inside
the body in every frame, the clip's quality figures, and writes them as JSON.

The simulation resumes where a killed run stopped (the fitted template and the simulator's
saved state are kept in ``--out``): run the same command again.

    OMP_NUM_THREADS=1 .venv/bin/python bench/quality/fit_dress.py --out runs/fit_dress

docs/use/YOUR_GARMENT.md quotes its output: 28 min in all on dev-cpu (one thread, the cores shared).
Exit status 1 when a vertex is deeper than 5 mm inside the body in some frame.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch

from loosefit.api import motion_for
from loosefit.atomic import atomic_path
from loosefit.body.avatar import Avatar, AvatarConfig
from loosefit.errors import LoosefitInputError
from loosefit.fitting.drape import FitConfig, FitReport, fit_garment
from loosefit.fitting.place import fit_dress, import_garment
from loosefit.garment.dress import DressConfig
from loosefit.garment.obj import write_obj
from loosefit.garment.quality import PENETRATION_TOLERANCE, quality
from loosefit.progress import tqdm_bar
from loosefit.sim.cloth_config import ClothConfig
from loosefit.sim.driver import simulate
from loosefit.sim.timeline import collider_meshes
from loosefit.types import GarmentTemplate

OTHER_BODY = {"weight": 0.8, "height": 0.9, "proportions": 0.0}  # as tests/fitting/test_drape.py
MOTION, FRAMES, FPS = "dance:4", 120, 30.0


def export_cm_y_up(template: GarmentTemplate, path: Path) -> Path:
    """The garment written in centimetres, Y up (the avatar's front, -Y, to +Z)."""
    v = template.vertices.astype(np.float64) * 100.0
    v = np.stack([v[:, 0], v[:, 2], -v[:, 1]], 1)
    write_obj(path, v.astype(np.float32), template.faces, template.uvs, template.face_uvs)
    return path


def fitted_dress(out: Path, avatar: Avatar) -> tuple[GarmentTemplate, dict]:
    """The dress made for :data:`OTHER_BODY`, exported and fitted to ``avatar`` (kept in
    ``out``: a second run reads it back)."""
    path, done = out / "other_dress.obj", out / "fitted.npz"
    if done.is_file():
        template = GarmentTemplate.load(done)
        return template, template.meta["fit"]
    dress = fit_dress(
        Avatar(AvatarConfig(shape=OTHER_BODY)), DressConfig.preset("cpu", "strapless")
    )
    export_cm_y_up(dress, path)
    try:
        import_garment(path, avatar, kind="dress")
        refused = "imported without --fit (not a conflict)"
    except LoosefitInputError as exc:  # what the plain import says, quoted
        refused = str(exc).splitlines()[0]
    fitted = fit_garment(path, config=FitConfig(), kind="dress", avatar=avatar)
    template, report = fitted.template, fitted.report
    print(f"without --fit: {refused}")
    print(f"fit: {report.format()}")
    template.meta["bench"] = {"without_fit": refused}
    with atomic_path(done) as tmp:
        template.save(tmp)
    return template, asdict(report)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("runs/fit_dress"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(1)

    avatar = Avatar()
    template, report = fitted_dress(args.out, avatar)
    fit = FitReport(**report)
    motion = motion_for(MOTION, avatar, FPS, frames=FRAMES)
    cloth = ClothConfig(arm_collision="upper")
    bar = tqdm_bar("simulate", unit="frame")
    t0 = time.perf_counter()
    result = simulate(
        avatar,
        template,
        motion,
        cloth,
        progress=bar.progress,
        resume=args.out / "resume.npz",
        resume_every=10,
    )
    bar.close()
    wall = time.perf_counter() - t0

    with torch.no_grad():
        body = avatar.pose_motion(motion).vertices.numpy()
    _, _, meshes = collider_meshes(avatar, cloth)
    g = result.garment_vertices
    deepest = np.array(
        [
            quality(g[t : t + 1], template, body[t : t + 1], meshes)["inside_depth_max"]
            for t in range(len(g))
        ]
    )
    q = result.quality
    worst = int(deepest.argmax())
    lines = [
        f"garment: the parametric strapless dress made for {OTHER_BODY}, {template.num_vertices}"
        f" vertices, cm, Y up; without --fit: {template.meta.get('bench', {}).get('without_fit')}",
        f"fit: {fit.format()}".replace("\n", "; "),
        f"simulated {MOTION} ({motion.num_frames} frames at {FPS:g} fps): "
        f"{result.seconds_per_frame:.2f} s per frame (one thread), {wall / 60:.1f} min this run",
        f"deepest vertex inside the body: {1000 * deepest.max():.1f} mm (frame {worst}); "
        f"frames with a vertex deeper than {1000 * PENETRATION_TOLERANCE:.0f} mm: "
        f"{int((deepest > PENETRATION_TOLERANCE).sum())} of {len(deepest)}",
        f"per frame (mm): {' '.join(f'{1000 * d:.1f}' for d in deepest)}",
        f"quality: inside (any depth) mean {100 * q['inside_mean']:.2f} %, max "
        f"{100 * q['inside_max']:.2f} %; strain p50 {q['strain_p50']:.3f}, p99 "
        f"{q['strain_p99']:.3f}, max {q['strain_max']:.3f} (against the file's rest lengths)",
    ]
    print("\n".join(lines))
    record = {
        "machine": f"{platform.node()} ({platform.processor() or platform.machine()}), torch "
        f"{torch.__version__}",
        "garment_vertices": template.num_vertices,
        "other_body": OTHER_BODY,
        "fit": report,
        "motion": MOTION,
        "frames": motion.num_frames,
        "seconds_per_frame": result.seconds_per_frame,
        "deepest_per_frame_m": deepest.tolist(),
        "quality": {k: v for k, v in q.items() if np.ndim(v) == 0},
        "lines": lines,
    }
    with atomic_path(args.out / "result.json") as tmp:
        tmp.write_text(json.dumps(record, indent=1, default=float))
    return 0 if deepest.max() <= PENETRATION_TOLERANCE else 1


if __name__ == "__main__":
    sys.exit(main())
