"""What several commands share: the log line, the avatar, motion capture, garment-file and
render flags, and the inference stages flags.

Each ``add_*_args`` adds one group of flags to a command's parser; the function beside it
turns those flags into what the API takes (``retarget_config``, ``build_avatar``,
``stages``, ...). Heavy libraries are imported inside the functions, so that building the
parser stays quick.
"""

from __future__ import annotations

import argparse
import sys
import time
from contextlib import contextmanager
from pathlib import Path

from loosefit.errors import LoosefitInputError


def log(msg: str) -> None:
    """One ``[loosefit]`` line on stderr (stdout is for reports)."""
    print(f"[loosefit] {msg}", file=sys.stderr, flush=True)


def log_exported(files: list) -> None:
    log(f"exported {len(files)} file(s): {files[0]}" + (" ..." if len(files) > 1 else ""))


# --- the avatar ---------------------------------------------------------------------------


def add_avatar_args(p: argparse.ArgumentParser) -> None:
    """``--shape`` and ``--device``: the avatar's body and the device it is posed on."""
    p.add_argument(
        "--shape",
        default="",
        help="body shape as anny phenotypes in [0, 1], e.g. 'gender=0.9,height=0.6,weight=0.4'",
    )
    p.add_argument("--device", default="cpu", help="torch device for posing (cpu, cuda)")


def parse_shape(text: str) -> dict[str, float]:
    """``--shape 'gender=0.9,height=0.6'`` as ``{"gender": 0.9, "height": 0.6}``."""
    shape = {}
    for item in filter(None, (s.strip() for s in text.split(","))):
        key, sep, value = item.partition("=")
        try:
            if not sep:
                raise ValueError
            shape[key.strip()] = float(value)
        except ValueError:
            raise LoosefitInputError("--shape", item, "NAME=VALUE", repr(item)) from None
    return shape


def build_avatar(args: argparse.Namespace):
    """The avatar of ``--shape`` on ``--device``."""
    from loosefit.api.motion import build_avatar as avatar_of

    t = time.perf_counter()
    log("building the avatar (anny; the first run builds its cache, about 2 minutes)")
    built = avatar_of(parse_shape(args.shape), device=args.device)
    log(f"avatar ready in {time.perf_counter() - t:.1f} s")
    return built


def frame_range(args: argparse.Namespace, num_frames: int) -> tuple[int, int | None]:
    """``--start-frame`` and ``--max-frames`` as a slice of a clip of ``num_frames``."""
    start = getattr(args, "start_frame", 0) or 0
    if not 0 <= start < num_frames:
        raise LoosefitInputError("--start-frame", "start_frame", f"0 to {num_frames - 1}", start)
    return start, (start + args.max_frames if args.max_frames else None)


def stored_clip(args: argparse.Namespace, shape: dict, motion, garment):
    """The avatar of a stored clip's body shape, and the clip cut to its frame range."""
    args.shape = ",".join(f"{k}={v}" for k, v in shape.items())
    built = build_avatar(args)
    built.check_motion(motion)
    start, stop = frame_range(args, motion.num_frames)
    if start or stop:
        motion, garment = motion.slice(start, stop), garment[start:stop]
    return built, motion, garment


# --- motion capture files -----------------------------------------------------------------


def add_bvh_args(p: argparse.ArgumentParser) -> None:
    """How a motion capture file is read and mapped: --units, --scale, --joint-map (BVH,
    glTF), --animation, --skin (glTF), --smpl-up (SMPL .npz), --no-pose-check."""
    from loosefit.api.motion import bvh_units  # no torch: the parser stays quick to build

    p.add_argument(
        "--units",
        default="auto",
        choices=bvh_units(),
        help="a BVH file's length unit (default: guessed from its skeleton's size; "
        "a dancer outside 1.2-2.2 m tall is refused)",
    )
    p.add_argument(
        "--scale",
        type=float,
        default=None,
        help="a BVH file's metres per unit, for other units (overrides --units)",
    )
    p.add_argument(
        "--joint-map",
        default="auto",
        metavar="MAP",
        help="a BVH file's joints: auto (a shipped map that fits, else matched "
        "by name and structure), daz, cmu_mb, or a .yaml/.toml file of 'avatar "
        "joint: your joint' lines (docs/use/INPUTS.md; inspect-motion shows the "
        "match)",
    )
    p.add_argument(
        "--animation",
        default=None,
        metavar="NAME",
        help="a glTF/GLB file's animation, by name or index (default: the first; "
        "inspect-motion lists them)",
    )
    p.add_argument(
        "--skin",
        default=None,
        metavar="NAME",
        help="a glTF/GLB file's skin, by name or index (default: the one its "
        "animation drives most)",
    )
    p.add_argument(
        "--smpl-up",
        default="auto",
        choices=("auto", "+x", "-x", "+y", "-y", "+z", "-z"),
        help="an SMPL .npz's world up axis (AMASS: +z; default: found from its root orientations)",
    )
    p.add_argument(
        "--no-pose-check",
        action="store_true",
        help="let through a motion capture whose retargeted poses fail the pose "
        "check (the body standing, its feet meeting the floor, no joint turning "
        "faster than a body can; docs/use/INPUTS.md)",
    )


def retarget_config(args: argparse.Namespace):
    """The RetargetConfig that --units, --scale, --joint-map, --animation, --skin,
    --smpl-up and --no-pose-check ask for."""
    from loosefit.api.motion import retarget_config as config

    return config(
        units=args.units,
        scale=args.scale,
        joint_map=args.joint_map,
        animation=args.animation,
        skin=args.skin,
        smpl_up=args.smpl_up,
        check_pose=not args.no_pose_check,
    )


# --- garments -----------------------------------------------------------------------------


def add_import_args(p: argparse.ArgumentParser) -> None:
    """How a garment file is read and placed (loosefit.fitting.place.import_garment)."""
    p.add_argument(
        "--units",
        default=None,
        choices=("m", "dm", "cm", "mm", "in"),
        help="a garment file's unit (default: guessed from its size)",
    )
    p.add_argument(
        "--up",
        default=None,
        choices=("z", "y", "-z", "-y"),
        help="a garment file's up axis (default: guessed from its openings)",
    )
    p.add_argument(
        "--kind",
        default=None,
        choices=("skirt", "dress"),
        help="skirt (waistband at the natural waist) or dress (on the shoulders, or "
        "its top band at the chest); default: a dress if it has straps",
    )
    p.add_argument(
        "--offset",
        default=None,
        metavar="X,Y,Z",
        help="metres to move a garment file by after placement",
    )
    p.add_argument(
        "--attach",
        default="auto",
        help="what the simulation holds: auto (the waistband, a strapless top band, "
        "or straps over the shoulders), top (the top opening), or a text file of "
        "vertex indices",
    )


def offset(text: str | None) -> tuple[float, float, float]:
    """``--offset X,Y,Z`` in metres (none: no move)."""
    if not text:
        return (0.0, 0.0, 0.0)
    try:
        x, y, z = (float(t) for t in text.split(","))
    except ValueError:
        raise LoosefitInputError(
            "--offset", "offset", "X,Y,Z in metres, e.g. 0,0,0.02", repr(text)
        ) from None
    return (x, y, z)


def garment_template(spec: str, avatar, resolution: str = "cpu", length: float | None = None):
    """A garment template in the avatar's rest frame from a style name or an OBJ file."""
    from loosefit.api.render import garment_template as template

    try:
        return template(spec, avatar=avatar, resolution=resolution, length=length)
    except LoosefitInputError as exc:
        raise LoosefitInputError("--garment", exc.field, exc.expected, exc.found) from exc


# --- rendering ----------------------------------------------------------------------------


def add_render_args(p: argparse.ArgumentParser, views: str = "front,three_quarter,side") -> None:
    """``--views``, ``--size``, ``--png-every``, ``--fixed-camera``: how ``render`` draws."""
    p.add_argument("--views", default=views, help="comma-separated camera views")
    p.add_argument("--size", type=int, default=480, help="pixels per view (square)")
    p.add_argument("--png-every", type=int, default=0, help="also save every Nth frame as PNG")
    p.add_argument(
        "--fixed-camera",
        action="store_true",
        help="frame the whole path once instead of following the dancer",
    )


def render(args, avatar, motion, template, garment_vertices, out: Path, *, title: str, body=None):
    """The body (posed here unless ``body`` is given) and the garment to a video in
    ``out``, as the render flags ask."""
    from loosefit.api.render import render_clip

    result = render_clip(
        out,
        avatar=avatar,
        motion=motion,
        title=title,
        template=template,
        garment=garment_vertices,
        body=body,
        size=args.size,
        views=[v.strip() for v in args.views.split(",") if v.strip()],
        follow=not args.fixed_camera,
        png_every=args.png_every,
    )
    log(f"wrote {result.video}")
    if result.sheet is not None:
        log(f"wrote {result.sheet}")
    return result


# --- a trained model's inference stages ---------------------------------------------------


def add_generative_arg(p: argparse.ArgumentParser) -> None:
    """``--generative``, for commands that load a motion checkpoint."""
    p.add_argument(
        "--generative",
        default=None,
        help="the generative checkpoint (default: the one the motion checkpoint records)",
    )


def add_stage_args(p: argparse.ArgumentParser) -> None:
    """``--detail`` and the flags that skip inference stages (read by ``stages``)."""
    p.add_argument(
        "--detail",
        default=None,
        help="a detail stage's model.pt (default: detail.pt beside a packaged motion.pt)",
    )
    p.add_argument("--no-detail", action="store_true", help="skip detail enhancement (3.4)")
    p.add_argument(
        "--no-lengths",
        action="store_true",
        help="skip the edge-length stage (edges back to rest length before collision)",
    )
    p.add_argument("--no-collision", action="store_true", help="skip collision handling (3.5)")
    p.add_argument(
        "--feedback",
        action="store_true",
        help="feed the garment after detail and collision back as the next frame's "
        "previous state (default: the decoders' output, as in training)",
    )


def stages(args: argparse.Namespace):
    """The inference stages the ``add_stage_args`` flags leave on."""
    from loosefit.api.options import stages as switched

    return switched(
        detail=not args.no_detail,
        lengths=not args.no_lengths,
        collision=not args.no_collision,
        feedback=args.feedback,
    )


def add_runtime_args(p: argparse.ArgumentParser) -> None:
    """``--runtime`` and ``--collision``: what runs a learned model's stages, and how."""
    p.add_argument(
        "--runtime",
        default="torch",
        choices=("torch", "onnx"),
        help="what runs the learned stages (motion stage, detail): torch (PyTorch), or onnx "
        "(onnxruntime: the same garments, faster on one core; pip install 'loosefit[onnx]'; "
        "the graphs are exported in memory at the start, about a second). Edge lengths and "
        "collision handling are the same either way (docs/use/ENGINE_EXPORT.md)",
    )
    p.add_argument(
        "--collision",
        default="full",
        choices=("full", "realtime"),
        help="collision handling: full, or realtime (one solve and one round of its last "
        "projection and mending a frame: 1.3-2.2x faster, a little more cloth left within a "
        "millimetre of the skin; docs/results/BENCHMARKS.md, 'real time on one core')",
    )


def add_threads_arg(p: argparse.ArgumentParser) -> None:
    """``--threads``: torch's intra-op threads while the model animates (read by
    ``inference_threads``)."""
    from loosefit.api.options import most_threads

    p.add_argument(
        "--threads",
        default=None,
        metavar="N",
        help="torch threads while the model animates (default: the free cores by the "
        f"machine's load average, at most {most_threads()}; OMP_NUM_THREADS, if set, is kept; "
        "docs/use/THREADS.md)",
    )


def threads_of(args: argparse.Namespace) -> int | None:
    """``--threads`` as a count (None: not given); commands check it before their work.

    Raises:
        LoosefitInputError: not a whole number >= 1.
    """
    if args.threads is None:
        return None
    try:
        asked = int(args.threads)
    except ValueError:
        asked = 0
    if asked < 1:
        raise LoosefitInputError(
            "--threads", "threads", "a whole number, at least 1", repr(args.threads)
        )
    return asked


@contextmanager
def inference_threads(args: argparse.Namespace):
    """Within the block, torch's threads as ``--threads`` asks (default: the policy of
    :func:`loosefit.api.options.torch_threads`), logged; torch's count before comes back
    after it.

    Raises:
        LoosefitInputError: ``--threads`` not a whole number >= 1.
    """
    from loosefit.api.options import most_threads, torch_threads

    with torch_threads(threads_of(args), source="--threads") as chosen:
        n = chosen.count
        if chosen.asked is not None:
            why = "as --threads asks"
        elif chosen.variable is not None:
            why = f"as {chosen.variable} sets"
        else:
            why = f"the free cores by the load average, at most {most_threads()}; --threads N"
        log(f"{n} torch thread{'s' if n > 1 else ''} ({why})")
        yield n


def open_model(path, generative=None, detail=None):
    """A trained model to animate with, through the API (:func:`loosefit.load`: any
    checkpoint the project writes, or a set's folder): an :class:`~loosefit.api.Animator`.

    Raises:
        LoosefitInputError: a missing file, or one that does not animate.
    """
    import loosefit

    if not Path(path).exists():
        raise LoosefitInputError(path, "<file>", "a checkpoint file", "no such file")
    return loosefit.load(path, generative=generative, detail=detail)


def add_export_format_args(p) -> None:
    """The options of an animation export (``--up-axis``, ``--body-points``)."""
    p.add_argument(
        "--up-axis",
        choices=("Y", "Z"),
        default=None,
        help="the exported axes (default: the format's own: USD Z up; Alembic, PC2 and OBJ Y "
        "up; glTF is always Y up)",
    )
    p.add_argument(
        "--body-points",
        action="store_true",
        help="the body as a point cache (every vertex every frame) rather than skinned (USD, glTF)",
    )


def export_config(args):
    """The export configuration (:func:`loosefit.api.options.export_config`) that
    ``add_export_format_args`` asked for."""
    from loosefit.api.options import export_config as config

    return config(up_axis=args.up_axis, skinned_body=not args.body_points)
