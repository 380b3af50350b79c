"""How many capture files of a data set are read without a joint map, as a plausible dancer.

Takes a fixed sample of a folder of motion files (BVH, glTF/GLB, SMPL ``.npz``): every
k-th file of the sorted list, ``--sample`` of them, so the same files on every run. Each
is read as ``loosefit animate`` reads it, without a joint map (the shipped maps, then the
joint matcher), and judged a plausible dancer when it stands as one: a dancer's height as
measured on the frames (1.2-2.2 m, what retargeting accepts), the avatar's root 0.7-1.1 m
above the floor in the median frame (a ballet clip's plies sink it below 0.8), its head
above its pelvis in at least 75 % of the frames (a cartwheel turns it over a while).
Prints, and writes with ``--out``, the share read, why the rest were refused (grouped by
the error's field and its first words) and each file's line::

    python bench/data/read_rate.py /path/to/studio/bvh --sample 78 --out read_rate.md

``--studio N`` makes a studio-style data set to read first (into ``--work``): the real
captures of ``../shared/mocap`` (CMU ballet and salsa) retargeted to the avatar and written
back as one studio rig writes them (``tests/motion/bvh_conventions.py``: centimetres, Y up,
bones along their local X at zero pose, a ``joint_Root`` at the origin; the capture's start
position baked into the hips' OFFSET, metres away, in some files; no OFFSETs at all in
others), N clips of up to ``--seconds`` each.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from loosefit.body.avatar import Avatar  # noqa: E402
from loosefit.errors import LoosefitInputError  # noqa: E402
from loosefit.motion.motions import load_motion  # noqa: E402

SUFFIXES = (".bvh", ".gltf", ".glb", ".npz")


def fixed_sample(folder: Path, n: int) -> list[Path]:
    """``n`` files of the folder's sorted motion files, evenly spaced (all if fewer)."""
    files = sorted(p for p in folder.rglob("*") if p.suffix.lower() in SUFFIXES)
    if len(files) <= n:
        return files
    return [files[i] for i in np.linspace(0, len(files) - 1, n).round().astype(int)]


def judge(path: Path, avatar: Avatar) -> tuple[str, str]:
    """("read", what) for a plausible dancer, ("refused", why) or ("implausible", why)."""
    from loosefit.motion.files import read_clip
    from loosefit.motion.retarget import RetargetConfig, source_height
    from tests.motion.bvh_conventions import joint_positions

    try:
        motion = load_motion(str(path), avatar, fps=None)
        height, _ = source_height(read_clip(path, RetargetConfig()))
    except LoosefitInputError as exc:
        return "refused", f"{exc.field}: {exc.found[:90]}"
    names = avatar.skeleton.names
    joints = joint_positions(avatar.skeleton, motion)
    root = float(np.median(motion.root_translation[:, 2]))
    upright = float((joints[:, names.index("Head"), 2] > joints[:, names.index("Hips"), 2]).mean())
    what = (
        f"{motion.meta['joint_map']}, {height:.2f} m tall, root {root:.2f} m, "
        f"head above pelvis in {upright:.0%} of {motion.num_frames} frames"
    )
    ok = 1.2 <= height <= 2.2 and 0.7 <= root <= 1.1 and upright >= 0.75
    return ("read" if ok else "implausible"), what


def make_studio(out: Path, n: int, seconds: float, avatar: Avatar) -> None:
    """N studio-rig BVH files from the shared real captures (see the module docstring)."""
    from tests.motion.bvh_conventions import STUDIO_X, write_convention_bvh

    mocap = ROOT.parent / "shared" / "mocap"
    sources = sorted(mocap.glob("cmu-*/*.bvh"))
    if not sources:
        sys.exit(f"no captures under {mocap}: --studio needs ../shared/mocap")
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    for i in range(n):
        src = sources[i % len(sources)]
        motion = load_motion(str(src), avatar, fps=30)
        length = int(seconds * 30)
        start = int(rng.integers(0, max(1, motion.num_frames - length)))
        motion = motion.slice(start, start + length)
        kind = ("origin", "far", "zero")[i % 3]
        conv = dataclasses.replace(
            STUDIO_X,
            name=f"studio-{kind}",
            start=None if kind == "origin" else tuple(rng.uniform(-8, 8, 2)) + (0.0,),
            zero_offsets=kind == "zero",
            orient_twist=float(rng.uniform(0, 60)),
        )
        path = out / f"{i:03d}_{src.stem}_{kind}.bvh"
        write_convention_bvh(path, conv, avatar.skeleton, motion, avatar.floor_height)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("folder", nargs="?", help="a folder of motion files (default: --work)")
    p.add_argument("--sample", type=int, default=78, help="files of the fixed sample")
    p.add_argument("--studio", type=int, default=0, help="make N studio-rig clips first")
    p.add_argument("--seconds", type=float, default=4.0, help="a made clip's length")
    p.add_argument("--work", default="out/read_rate", help="where --studio writes its clips")
    p.add_argument("--out", help="a markdown file for the table")
    p.add_argument("--machine", default="dev-cpu", help="the machine's name, for the table")
    args = p.parse_args()
    avatar = Avatar()
    folder = Path(args.folder or args.work)
    if args.studio:
        make_studio(folder, args.studio, args.seconds, avatar)
    files = fixed_sample(folder, args.sample)
    if not files:
        sys.exit(f"no motion files ({', '.join(SUFFIXES)}) under {folder}")
    rows, verdicts = [], Counter()
    t0 = time.perf_counter()
    for k, path in enumerate(files):
        verdict, what = judge(path, avatar)
        verdicts[verdict] += 1
        rows.append((path.relative_to(folder), verdict, what))
        rate = (k + 1) / (time.perf_counter() - t0)
        print(
            f"[{k + 1}/{len(files)}, {rate:.2f} files/s, ETA {(len(files) - k - 1) / rate:.0f} "
            f"s] {path.name}: {verdict}: {what}",
            file=sys.stderr,
        )
    reasons = Counter(
        what.split(":")[0] + ": " + what.split(":", 1)[1][:50]
        for _, v, what in rows
        if v == "refused"
    )
    share = verdicts["read"] / len(files)
    lines = [
        f"# Read without a joint map: {folder.name}",
        "",
        f"{args.machine}, {datetime.date.today()}: `python bench/data/read_rate.py "
        f"{args.folder or args.work} --sample {args.sample}"
        + (f" --studio {args.studio}" if args.studio else "")
        + "`",
        "",
        f"**{verdicts['read']} of {len(files)} read as a plausible dancer ({share:.1%})**; "
        f"{verdicts['refused']} refused, {verdicts['implausible']} read but implausible.",
        "",
    ]
    if reasons:
        lines += ["| refused because | files |", "| --- | ---: |"]
        lines += [f"| {r} | {c} |" for r, c in reasons.most_common()]
        lines.append("")
    lines += ["| file | verdict | what |", "| --- | --- | --- |"]
    lines += [f"| {f} | {v} | {w.replace('|', '/')} |" for f, v, w in rows]
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        Path(args.out).write_text(text)


if __name__ == "__main__":
    main()
