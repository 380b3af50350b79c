"""docs/img/character_blender.png and docs/img/character_fit.png: a character built in code
(anny of another phenotype re-skinned to a Mixamo skeleton, +Y up, ``tests/character/
character_file.py``), dressed by the pretrained set, its own ``.glb`` written back with the
skirt and opened in real Blender (``bpy``); and the fitted anny beside it::

    python bench/quality/character_blender.py

Prints the fit, collision handling's figures against the character's mesh and the time.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import loosefit  # noqa: E402
import loosefit.export  # noqa: E402
from loosefit.character import fit_character  # noqa: E402
from loosefit.character.sheet import character_sheet  # noqa: E402
from tests.character.character_file import write_character  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--img", default="docs/img")
    p.add_argument("--frames", type=int, default=60)
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path, _, _ = write_character(Path(tmp) / "character.glb", frames=args.frames)
        model = loosefit.load()
        t0 = time.perf_counter()
        dressed = model.dress(path, threads=1)
        seconds = time.perf_counter() - t0
        print(f"fitted: {dressed.fit.describe()}")
        inside = max(r["inside_after"] for r in dressed.collisions)
        deepest = max(r["depth_after"] for r in dressed.collisions)
        print(
            f"dressed {len(dressed.vertices)} frames in {seconds:.1f} s; against the "
            f"character's mesh: at most {inside} vertices inside in a frame, deepest "
            f"{1000 * deepest:.1f} mm"
        )
        glb = dressed.export(Path(tmp) / "dressed.glb")[0]
        reader = Path(loosefit.export.__file__).with_name("blender_read.py")
        png = Path(args.img) / "character_blender.png"
        cmd = [
            sys.executable,
            str(reader),
            str(glb),
            "--fps",
            "30",
            "--frames",
            "0",
            "--out",
            str(Path(tmp) / "seen.npz"),
            "--png",
            str(png),
            "--png-frame",
            str(args.frames // 2),
        ]
        subprocess.run(cmd, check=True, capture_output=True)
        print(f"wrote {png}")
        fitted = fit_character(model.model, path)
        sheet = Path(args.img) / "character_fit.png"
        character_sheet(fitted, model.model.avatar().faces.cpu().numpy(), sheet, size=360)
        print(f"wrote {sheet}")


if __name__ == "__main__":
    main()
