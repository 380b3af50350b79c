"""Contact sheets of retargeting: a capture's skeleton beside the avatar, in three conventions.

A procedural dance on the avatar is written as a BVH file in a rig convention of another
tool (built in code by ``tests/motion/bvh_conventions.py``: no outside file), read back as
``loosefit animate`` reads it, without a joint map, and drawn by ``loosefit inspect-motion
--sheet`` (the file's skeleton from its own forward kinematics, left; the retargeted avatar,
right). The conventions: a studio rig whose every bone lies along its own local X axis at
zero pose (centimetres, six channels a joint, joint orients twisted about the bones),
Mixamo (``mixamorig:`` names, centimetres, Y up), Unreal (``thigh_l``, A-pose), and the
conventions of a whole studio data set: the hips' OFFSET metres from a ``joint_Root`` of no
geometry (the capture's start baked in; as BVH and as GLB), and no OFFSETs at all, every
bone in the frames' position channels (the studio rig, and Mixamo's)::

    python bench/data/retarget_sheets.py --out docs/img
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from loosefit.body.avatar import Avatar  # noqa: E402
from loosefit.cli import main as cli  # noqa: E402
from loosefit.motion.bvh import read_bvh  # noqa: E402
from loosefit.motion.motions import load_motion  # noqa: E402
from tests.motion.bvh_conventions import (  # noqa: E402
    MIXAMO,
    MIXAMO_ZERO,
    STUDIO_FAR,
    STUDIO_X,
    STUDIO_ZERO,
    UNREAL,
    write_convention_bvh,
)
from tests.motion.gltf_writer import write_gltf  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="docs/img")
    p.add_argument("--motion", default="dance:3", help="a procedural motion on the avatar")
    p.add_argument("--frames", type=int, default=3, help="pictures a sheet")
    p.add_argument("--format", default="png", choices=("png", "jpg"), help="the sheets' format")
    args = p.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    avatar = Avatar()
    motion = load_motion(args.motion, avatar, seed=3)
    for conv, glb in (
        (STUDIO_X, False),
        (MIXAMO, False),
        (UNREAL, False),
        (STUDIO_FAR, True),
        (STUDIO_ZERO, False),
        (MIXAMO_ZERO, False),
    ):
        bvh = out / f".retarget_{conv.name}.bvh"
        write_convention_bvh(bvh, conv, avatar.skeleton, motion, avatar.floor_height)
        files = {conv.name: bvh}
        if glb:
            files[f"{conv.name}-glb"] = write_gltf(
                out / f".retarget_{conv.name}.glb", read_bvh(bvh)
            )
        for name, path in files.items():
            sheet = out / f"retarget_{name}.{args.format}"
            code = cli(
                [
                    "inspect-motion",
                    str(path),
                    "--sheet",
                    str(sheet),
                    "--sheet-frames",
                    str(args.frames),
                ]
            )
            if code != 0:
                raise SystemExit(f"{name}: inspect-motion refused it (exit {code})")
            print(f"{name}: {sheet}")
        for path in files.values():
            path.unlink()


if __name__ == "__main__":
    main()
