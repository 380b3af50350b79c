"""The ``loosefit`` command: thin wiring from arguments to one function each.

Subcommands:
    demo     pose the avatar with a procedural dance, dress it, write a video
    render   render a motion (BVH, saved or procedural) or a saved sequence to MP4 + PNG
    motion   convert a BVH, glTF or SMPL file or a procedural move to a motion file (.npz)
    inspect-motion  a motion file's joints, how they map onto the avatar, height, units
    garment  make a parametric skirt or import an OBJ, write OBJ + template (.npz)
    simulate simulate a garment dataset with Newton's VBD cloth solver
    dataset  pack a data set small enough to share, or unpack one (verified)
    view     sequences in a 3D viewer in the browser (body, garment, colour by error)
    export-model  the learned runtime as ONNX (+ JSON) for a game engine
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import time
from pathlib import Path

from loosefit.errors import LoosefitInputError


def _log(msg: str) -> None:
    print(f"[loosefit] {msg}", file=sys.stderr, flush=True)


def _add_view_args(p: argparse.ArgumentParser) -> None:
    from loosefit.view.config import COLOURINGS  # light: viser is imported on start

    p.add_argument(
        "--port",
        type=int,
        default=8080,
        help="the first port tried (taken: the next free one, printed)",
    )
    p.add_argument(
        "--host", default="127.0.0.1", help="the address to listen on (0.0.0.0: every interface)"
    )
    p.add_argument(
        "--colour",
        default="plain",
        choices=tuple(COLOURINGS),
        help="colour the garment by: its distance to the reference (error), edge "
        "strain, or depth inside the body (changeable in the panel)",
    )
    p.add_argument(
        "--reference",
        type=int,
        default=0,
        help="the sequence the distance and RMSE are measured to (0: the first)",
    )
    p.add_argument(
        "--overlay",
        action="store_true",
        help="overlaid rather than side by side (changeable in the panel)",
    )
    p.add_argument("--paused", action="store_true", help="start paused")
    p.add_argument(
        "--pixel-ratio",
        type=float,
        default=None,
        help="the canvas's pixels per screen pixel, fixed (e.g. 0.5 for a browser drawing "
        "WebGL without a GPU: a quarter of the pixels, a frame drawn in about 40%% less time; "
        "start Chromium with --webgl-antialiasing-mode=none as well; default: the "
        "browser's, lowered by viser while frames are slow)",
    )


def _add_avatar_args(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--shape",
        default="",
        help="body shape as anny phenotypes in [0, 1], e.g. 'gender=0.9,height=0.6,weight=0.4'",
    )
    p.add_argument("--device", default="cpu", help="torch device for posing (cpu, cuda)")


def _add_generative_arg(p: argparse.ArgumentParser) -> None:
    """``--generative``, for commands that load a motion checkpoint."""
    p.add_argument(
        "--generative",
        default=None,
        help="the generative checkpoint (default: the one the motion checkpoint records)",
    )


def _add_render_args(p: argparse.ArgumentParser, views: str = "front,three_quarter,side") -> None:
    p.add_argument("--views", default=views, help="comma-separated camera views")
    p.add_argument("--size", type=int, default=480, help="pixels per view (square)")
    p.add_argument("--png-every", type=int, default=0, help="also save every Nth frame as PNG")
    p.add_argument(
        "--fixed-camera",
        action="store_true",
        help="frame the whole path once instead of following the dancer",
    )


def _add_bvh_args(p: argparse.ArgumentParser, units: tuple[str, ...]) -> None:
    """How a motion capture file is read and mapped: --units, --scale, --joint-map (BVH,
    glTF), --animation, --skin (glTF), --smpl-up (SMPL .npz)."""
    p.add_argument("--units", default="auto", choices=units,
                   help="a BVH file's length unit (default: guessed from its skeleton's size; "
                   "a dancer outside 1.2-2.2 m tall is refused)")  # fmt: skip
    p.add_argument(
        "--scale",
        type=float,
        default=None,
        help="a BVH file's metres per unit, for other units (overrides --units)",
    )
    p.add_argument("--joint-map", default="auto", metavar="MAP",
                   help="a BVH file's joints: auto (a shipped map that fits, else matched "
                   "by name and structure), daz, cmu_mb, or a .yaml/.toml file of 'avatar "
                   "joint: your joint' lines (docs/INPUTS.md; inspect-motion shows the "
                   "match)")  # fmt: skip
    p.add_argument("--animation", default=None, metavar="NAME",
                   help="a glTF/GLB file's animation, by name or index (default: the first; "
                   "inspect-motion lists them)")  # fmt: skip
    p.add_argument("--skin", default=None, metavar="NAME",
                   help="a glTF/GLB file's skin, by name or index (default: the one its "
                   "animation drives most)")  # fmt: skip
    p.add_argument("--smpl-up", default="auto", choices=("auto", "+x", "-x", "+y", "-y", "+z",
                   "-z"), help="an SMPL .npz's world up axis (AMASS: +z; default: found from "
                   "its root orientations)")  # fmt: skip
    p.add_argument("--no-pose-check", action="store_true",
                   help="let through a motion capture whose retargeted poses fail the pose "
                   "check (the body standing, its feet meeting the floor, no joint turning "
                   "faster than a body can; docs/INPUTS.md)")  # fmt: skip


def _retarget_config(args: argparse.Namespace):
    """The RetargetConfig that --units, --scale, --joint-map, --animation, --skin and
    --smpl-up ask for."""
    from loosefit.body.retarget import RetargetConfig

    return RetargetConfig(units=args.units, scale=args.scale, joint_map=args.joint_map,
                          animation=args.animation, skin=args.skin, smpl_up=args.smpl_up,
                          check_pose=not args.no_pose_check)  # fmt: skip


def _parse_shape(text: str) -> dict[str, float]:
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


def _avatar(args: argparse.Namespace):
    from loosefit.body.avatar import Avatar, AvatarConfig

    t = time.perf_counter()
    _log("building the avatar (anny; the first run builds its cache, about 2 minutes)")
    avatar = Avatar(AvatarConfig(shape=_parse_shape(args.shape)), device=args.device)
    _log(f"avatar ready in {time.perf_counter() - t:.1f} s")
    return avatar


def _garment(spec: str, avatar, resolution: str = "cpu", length: float | None = None):
    """A garment template in the avatar's rest frame from a style name or an OBJ file."""
    from loosefit.dress import garment_for

    try:
        return garment_for(spec, avatar, resolution, length)
    except LoosefitInputError as exc:
        raise LoosefitInputError("--garment", exc.field, exc.expected, exc.found) from exc


def _render(args, avatar, motion, template, garment_vertices, out: Path, title: str, body=None):
    from loosefit.render.clip import render_clip
    from loosefit.render.renderer import RenderConfig, RenderMesh

    body = body if body is not None else avatar.pose_motion(motion)
    scene = [
        RenderMesh(avatar.faces.cpu().numpy(), body.vertices.cpu().numpy(), "body", name="body")
    ]
    if template is not None:
        scene.append(RenderMesh(template.faces, garment_vertices, "garment", name=template.name))
    config = RenderConfig(
        width=args.size,
        height=args.size,
        views=tuple(v.strip() for v in args.views.split(",") if v.strip()),
        follow=not args.fixed_camera,
    )
    result = render_clip(
        scene, out, fps=motion.fps, config=config, title=title, png_every=args.png_every
    )
    _log(f"wrote {result.video}")
    if result.sheet is not None:
        _log(f"wrote {result.sheet}")
    return result


def cmd_demo(args: argparse.Namespace) -> int:
    """The main job: the pretrained model animating its skirt on a dance (``--physics``: the
    simulator instead; ``--no-physics``: the skirt carried rigidly)."""
    from loosefit.body.motions import load_motion
    from loosefit.dress import carry_rigidly
    from loosefit.sequence import AnimatedGarment

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    learned = not (args.physics or args.no_physics)
    if learned and args.garment is not None:
        raise LoosefitInputError("--garment", "garment", "no --garment: the pretrained model "
                                 "animates the skirt it was trained on (use --physics to "
                                 "simulate another)", repr(args.garment))  # fmt: skip
    spec = args.motion or ("dance:20" if learned else "spin")
    max_frames = args.max_frames if args.max_frames or learned else 90
    model = None
    if learned:
        from loosefit.api import pretrained_checkpoint
        from loosefit.inference.animator import load_pipeline

        path = Path(args.checkpoint) if args.checkpoint else pretrained_checkpoint()
        model = load_pipeline(path)
        _trained_on_note(path)
        _physics_note(model, model.stages)
        avatar, template = model.avatar(), model.template
    else:
        avatar = _avatar(args)
        template = _garment(args.garment or "flared", avatar, args.resolution)
    motion = load_motion(spec, avatar, fps=model.fps if model else args.fps, seed=args.seed,
                         retarget=_retarget_config(args), max_frames=max_frames,
                         start_frame=args.start_frame)  # fmt: skip
    _log(f"motion '{motion.name}': {motion.num_frames} frames at {motion.fps:g} fps")
    body = avatar.pose_motion(motion)
    if model is not None:
        bar = tqdm_bar("animate", unit="frame")
        result = model.animate(motion, progress=bar.progress, runtime=args.runtime,
                               collision=args.collision)  # fmt: skip
        bar.close()
        garment, source = result.vertices, f"loosefit model {path.parent.name}"
        _log(_throughput(motion, result) + "; " + _stage_line(model, model.stages, result))
    elif args.no_physics:
        garment = carry_rigidly(template, body, avatar).cpu().numpy()
        source = "rigid"
    else:
        from loosefit.dress import collider_arms
        from loosefit.sim.cloth import ClothConfig, simulate

        config = ClothConfig(device=args.sim_device, seed=args.seed,
                             arm_collision=collider_arms(template))  # fmt: skip
        bar = tqdm_bar("simulate", unit="frame")
        result = simulate(avatar, template, motion, config, progress=bar.progress)
        bar.close()
        garment, source = result.garment_vertices, "newton-vbd"
        q = result.quality
        _log(
            f"simulated at {result.seconds_per_frame:.2f} s/frame; garment inside the body: "
            f"{q['inside_max']:.4f} (worst frame), edge strain p99 {q['strain_p99']:.3f}"
        )
    seq = AnimatedGarment(
        motion, template, garment, {"rig": avatar.config.rig, "shape": avatar.shape}, source
    )
    seq.save(out / "sequence.npz")
    _log(f"wrote {out / 'sequence.npz'} ({source})")
    if learned:  # the body posed above, once for both files
        from loosefit.export import export_animation, garment_and_body

        meshes = garment_and_body(template, garment, body.vertices.cpu().numpy(),
                                  avatar.faces.cpu().numpy())  # fmt: skip
        for suffix in (".usdc", ".pc2"):
            _log_exported(export_animation(out / f"demo{suffix}", meshes, motion.fps))
    title = f"loosefit demo: {motion.name}" + (" (learned)" if learned else f" ({source})")
    _render(args, avatar, motion, template, garment, out, title, body=body)
    if args.view:
        _serve([seq], [f"demo ({source})"], [str(out / "sequence.npz")], args)
    return 0


class tqdm_bar:  # noqa: N801 - reads like the tqdm call it wraps
    """A tqdm bar fed by ``progress(done, total)`` callbacks."""

    def __init__(self, desc: str, unit: str) -> None:
        from tqdm import tqdm

        self.bar = tqdm(total=0, desc=desc, unit=unit)

    def progress(self, done: int, total: int) -> None:
        if self.bar.total != total:
            self.bar.total = total
        self.bar.update(done - self.bar.n)

    def close(self) -> None:
        self.bar.close()


class StageBars:
    """One tqdm bar per stage of a long job, fed by ``progress(stage, done, total)``
    callbacks: a stage's bar opens when it starts (its count, rate and time to go) and stays
    on screen, with its time, when the next one starts."""

    def __init__(self, prefix: str, units: dict[str, str]) -> None:
        self.prefix, self.units = prefix, units
        self.stage, self.bar = None, None

    def progress(self, stage: str, done: int, total: int) -> None:
        from tqdm import tqdm

        if stage != self.stage:
            self.close()
            self.stage = stage
            one = "{desc}: done in {elapsed}" if total == 1 else None  # no rate for one step
            self.bar = tqdm(total=total or None, desc=f"{self.prefix}: {stage}",
                            unit=self.units.get(stage, "step"), bar_format=one)  # fmt: skip
        if total and self.bar.total != total:
            self.bar.total = total
        self.bar.update(done - self.bar.n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
        self.stage, self.bar = None, None


def _frame_range(args, num_frames: int) -> tuple[int, int | None]:
    """``--start-frame`` and ``--max-frames`` as a slice of a clip of ``num_frames``."""
    start = getattr(args, "start_frame", 0) or 0
    if not 0 <= start < num_frames:
        raise LoosefitInputError("--start-frame", "start_frame", f"0 to {num_frames - 1}", start)
    return start, (start + args.max_frames if args.max_frames else None)


def _stored_clip(args, shape: dict, motion, garment):
    """The avatar of a stored clip's body shape, and the clip cut to its frame range."""
    args.shape = ",".join(f"{k}={v}" for k, v in shape.items())
    avatar = _avatar(args)
    avatar.check_motion(motion)
    start, stop = _frame_range(args, motion.num_frames)
    if start or stop:
        motion, garment = motion.slice(start, stop), garment[start:stop]
    return avatar, motion, garment


def read_any_sequence(path: str | Path, reader=None):
    """A sequence ``.npz``: an animated garment's file, or a data set's clip (a clip of an
    earlier data set, without the sequence format, is read through its data set)."""
    from loosefit.data.format import DatasetReader
    from loosefit.sequence import AnimatedGarment

    path = Path(path)
    root = path.parent.parent
    if reader is None and path.parent.name == "sequences" and (root / "manifest.json").is_file():
        reader = DatasetReader(root, allow_incomplete=True)
    if reader is not None:
        return reader.read(path.stem)
    return AnimatedGarment.load(path)


def cmd_render(args: argparse.Namespace) -> int:
    from loosefit.body.motions import load_motion
    from loosefit.dress import carry_rigidly

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    body = None
    if args.sequence or args.dataset:
        if args.sequence:
            seq = read_any_sequence(args.sequence)
            title = f"{Path(args.sequence).stem} ({seq.source})"
        else:
            from loosefit.data.format import DatasetReader

            reader = DatasetReader(args.dataset, allow_incomplete=True)
            name = args.clip or reader.split("all")[0]
            seq = reader.read(name)
            title = f"{Path(args.dataset).name}/{name} ({seq.source})"
        avatar, motion, garment = _stored_clip(args, seq.avatar.get("shape", {}), seq.motion,
                                               seq.garment_vertices)  # fmt: skip
        template = seq.garment
    elif args.motion:
        avatar = _avatar(args)
        motion = load_motion(args.motion, avatar, fps=args.fps, seed=args.seed,
                             retarget=_retarget_config(args))  # fmt: skip
        start, stop = _frame_range(args, motion.num_frames)
        motion = motion.slice(start, stop)
        template = _garment(args.garment, avatar)
        garment = None
        if template is not None:
            body = avatar.pose_motion(motion)
            garment = carry_rigidly(template, body, avatar).cpu().numpy()
        title = motion.name
    else:
        raise LoosefitInputError(
            "loosefit render", "arguments", "--motion, --sequence or --dataset", "none"
        )
    if args.start_frame:
        title += f", from frame {args.start_frame}"
    _log(f"rendering {motion.num_frames} frames")
    _render(args, avatar, motion, template, garment, out, title, body=body)
    return 0


def cmd_motion(args: argparse.Namespace) -> int:
    from loosefit.body.motions import load_motion

    avatar = _avatar(args)
    motion = load_motion(args.spec, avatar, fps=args.fps, seed=args.seed,
                         retarget=_retarget_config(args), max_frames=args.max_frames)  # fmt: skip
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    motion.save(out)
    _log(f"wrote {out}: {motion.num_frames} frames at {motion.fps:g} fps, {motion.duration:.1f} s")
    return 0


def cmd_inspect_motion(args: argparse.Namespace) -> int:
    from loosefit.body.inspect_motion import inspect_motion
    from loosefit.body.joint_match import joint_map_template

    config = _retarget_config(args)
    report = inspect_motion(args.file, config)
    print(report.format())
    if args.write_joint_map:
        out = Path(args.write_joint_map)
        out.write_text(joint_map_template(report.clip.joint_names, report.match, str(args.file),
                                          (report.up, report.forward)))  # fmt: skip
        _log(f"wrote {out}: correct it and pass --joint-map {out}")
    if report.error is not None:
        raise report.error
    if args.sheet:
        _motion_sheet(args, report.clip, config)
    return 0


def _motion_sheet(args: argparse.Namespace, clip, config) -> None:
    """inspect-motion --sheet: retarget at the file's rate, check the poses, draw the sheet."""
    import dataclasses

    from PIL import Image

    from loosefit.body.inspect_motion import sheet_inputs
    from loosefit.body.pose_check import check_pose
    from loosefit.body.retarget import retarget_bvh
    from loosefit.render.skeleton_sheet import skeleton_sheet

    avatar = _avatar(args)
    # drawn whatever the checks say: the sheet is how to see why they fail
    loose = dataclasses.replace(config, fps=None, check_pose=False, check_height=False)
    motion = retarget_bvh(clip, avatar.skeleton, avatar.floor_height, loose)
    refusal = None
    try:
        check_pose(motion, avatar.skeleton, avatar.floor_height, str(args.file))
        print("pose check: passes (standing, feet on the floor, no joint too fast)")
    except LoosefitInputError as exc:
        print(f"pose check: fails: {exc.found}")
        refusal = exc if config.check_pose else None
    sheet = sheet_inputs(clip, motion, loose, args.sheet_frames)
    body = avatar.pose_motion(sheet.motion).vertices.cpu().numpy()
    image = skeleton_sheet(sheet.points, sheet.bones, body, avatar.faces.cpu().numpy(),
                           sheet.frames)  # fmt: skip
    out = Path(args.sheet)
    out.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(image).save(out)
    _log(f"wrote {out}: the capture's skeleton (left) beside the avatar, frames {sheet.frames}")
    if refusal is not None:
        raise refusal


def _offset(text: str | None) -> tuple[float, float, float]:
    if not text:
        return (0.0, 0.0, 0.0)
    try:
        x, y, z = (float(t) for t in text.split(","))
    except ValueError:
        raise LoosefitInputError("--offset", "offset", "X,Y,Z in metres, e.g. 0,0,0.02",
                                 repr(text)) from None  # fmt: skip
    return (x, y, z)


def _fit_file(args: argparse.Namespace):
    """``garment FILE --fit``: the file fitted to the avatar (or, ``--shape auto``, to the
    anny body it fits best); the template, the import's report, the fit's, the avatar."""
    from loosefit.fit import STAGE_UNITS, FitConfig, fit_garment

    auto = args.shape.strip() == "auto"
    if auto:
        _log("--shape auto: searching anny's weight, height and proportions for the body the "
             "garment fits best")  # fmt: skip
    bars = StageBars("fit", STAGE_UNITS)
    try:
        template, fit, avatar = fit_garment(
            args.source, "auto" if auto else None, FitConfig(settle_seconds=args.settle),
            args.units, args.up, args.kind, _offset(args.offset), args.attach,
            avatar=None if auto else _avatar(args), progress=bars.progress,
        )  # fmt: skip
    finally:
        bars.close()
    return template, template.meta["import"], fit, avatar


def _fit_preview(path: Path, template, fit, avatar, size: int = 480) -> bool:
    """A front and side picture of a fitted garment on the avatar's rest pose, standing on
    the floor, written to ``path``; False (and why, logged) where nothing can render."""
    import numpy as np

    from loosefit.render.clip import render_still
    from loosefit.render.renderer import RenderConfig, RenderMesh

    up = np.array([0.0, 0.0, avatar.floor_height], np.float32)  # the rest pose's feet on z = 0
    body = avatar.rest_vertices.float().cpu().numpy() + up
    scene = [
        RenderMesh(avatar.faces.cpu().numpy(), body, "body", name="body"),
        RenderMesh(template.faces, template.vertices + up, "garment", name=template.name),
    ]
    title = (f"{template.name} fitted: {fit.inside_after} of {template.num_vertices} vertices "
             f"inside the body, moved by at most {100 * fit.moved_max:.1f} cm")  # fmt: skip
    config = RenderConfig(width=size, height=size, views=("front", "side"), frame_counter=False)
    try:
        render_still(scene, path, config, title)
    except RuntimeError as exc:  # no OpenGL here: the garment is written all the same
        _log(f"no preview picture: {exc}")
        return False
    return True


def cmd_garment(args: argparse.Namespace) -> int:
    from loosefit.garment.obj import write_obj

    is_file = Path(args.source).suffix.lower() in (".obj", ".gltf", ".glb")
    if args.fit and not is_file:
        raise LoosefitInputError("--fit", "source", "a garment file (.obj, .gltf, .glb) made "
                                 "for another body", repr(args.source))  # fmt: skip
    if args.fit:
        template, report, fit, avatar = _fit_file(args)
    elif is_file:
        from loosefit.dress import import_garment

        avatar = _avatar(args)
        template, report = import_garment(args.source, avatar, args.units, args.up, args.kind,
                                          _offset(args.offset), args.attach)  # fmt: skip
    else:
        template = _garment(args.source, _avatar(args), args.resolution, args.length)
        if template is None:
            raise LoosefitInputError("loosefit garment", "source", "a style or a file", "'none'")
    if is_file:
        for key in ("units", "up", "kind"):
            r = report[key]
            how = "guessed" if r["guessed"] else "given"
            extra = (f" (it is then {r['height_m']:.2f} m high, {r['width_m']:.2f} m wide)"
                     if key == "units" and r["guessed"] else "")  # fmt: skip
            _log(f"{key}: {r['value']} ({how}){extra}"
                 + (f"; say --{key} to change it" if r["guessed"] else ""))  # fmt: skip
        shift = report["placement"]["translation_m"]
        _log(f"placed: {report['placement']['rule']} (moved by "
             f"{', '.join(f'{100 * t:.1f}' for t in shift)} cm); held by "
             f"{report['attachment']['vertices']} vertices ({report['attachment']['as']}); "
             f"UVs: {report['uv_source']}")  # fmt: skip
    if args.fit:
        for line in fit.format().splitlines():
            _log(f"fitted: {line}")
        shape = ",".join(f"{k}={v:g}" for k, v in avatar.shape.items())
        _log(f"fitted to the avatar {shape}" + (f" ({fit.shape_tried} shapes tried): simulate "
             f"it with --shape {shape}" if fit.shape_tried else ""))  # fmt: skip
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    name = Path(args.source).stem
    write_obj(
        out / f"{name}.obj", template.vertices, template.faces, template.uvs, template.face_uvs
    )
    template.save(out / f"{name}.npz")
    _log(
        f"wrote {out / (name + '.obj')} and {out / (name + '.npz')}: {template.num_vertices} "
        f"vertices, {len(template.faces)} faces, {len(template.waist)} attached vertices "
        f"(metres, Z up, on the avatar's rest pose)"
    )
    if args.fit:
        preview = out / f"{name}.preview.png"
        if _fit_preview(preview, template, fit, avatar):
            _log(f"wrote {preview}: the fitted garment on the avatar, front and side (check it)")
    return 0


def dataset_config(args: argparse.Namespace):
    """The data set ``simulate`` makes: ``--config FILE`` or ``--preset``, then
    ``--garment``, ``--motions``, ``--test``, ``--device``, ``--max-frames``,
    ``--keep-poses`` over it."""
    from loosefit.sim.generate import (
        GarmentFile,
        MotionSource,
        preset,
        read_config_file,
    )

    config = read_config_file(args.config) if args.config else preset(args.preset, args.bvh)
    if args.garment:
        from loosefit.garment.dress import DRESS_SPECS, DressConfig
        from loosefit.garment.skirt import STYLES, SkirtConfig

        g = args.garment
        if g in STYLES:
            config.garment = SkirtConfig.preset(args.resolution, g)
        elif g in DRESS_SPECS:
            config.garment = DressConfig.preset(args.resolution, DRESS_SPECS[g])
        else:
            config.garment = GarmentFile(str(Path(g).resolve()), args.units, args.up, args.kind,
                                         _offset(args.offset), args.attach)  # fmt: skip
        config.preset = "custom"
        kind = "dress" if g in DRESS_SPECS else "skirt" if g in STYLES else args.kind
        if kind is None:  # a file: a dress if it has straps (as the import will guess)
            from loosefit.garment.importer import detect_kind, read_garment_mesh

            kind = detect_kind(read_garment_mesh(g).faces)
        if kind == "dress" and config.cloth.arm_collision is False:
            config.cloth.arm_collision = "upper"  # a dress's bodice reaches the upper arms
    if args.motions:
        folder = Path(args.motions)
        if folder.is_dir():
            config.motions = MotionSource(kind="bvh", folder=str(folder.resolve()),
                                          test=tuple(args.test or ()))  # fmt: skip
        else:
            specs = tuple(t for t in args.motions.split(",") if t)
            config.motions = MotionSource(kind="specs", specs=specs, test=tuple(args.test or ()))
        config.preset = "custom"
    elif args.test:
        config.motions.test = tuple(args.test)
    if args.device:
        config.cloth.device = args.device
    if getattr(args, "shape", ""):  # the avatar's body: the manifest carries it on to training
        config.shape = _parse_shape(args.shape)
        config.preset = "custom"
    if args.max_frames is not None:
        config.motions.max_frames = args.max_frames
    if getattr(args, "keep_poses", False):
        config.unfold.enabled = False
    return config


def cmd_simulate(args: argparse.Namespace) -> int:
    from loosefit.sim.generate import format_report, generate, write_config_file

    config = dataset_config(args)
    if args.write_config:
        write_config_file(config, args.write_config)
        _log(f"wrote {args.write_config}: `loosefit simulate --config {args.write_config}` "
             "makes this data set")  # fmt: skip
        return 0
    if args.out is None:
        args.out = f"datasets/{config.preset}"
    cluster = None
    if args.ray is not None:  # --ray [ADDRESS]: every clip a task on a Ray cluster
        from loosefit.sim.cluster import ClusterConfig

        cluster = ClusterConfig(address=args.ray or None)
    manifest = generate(
        config, args.out, workers=args.workers, progress=True, reuse=args.reuse, batch=args.batch,
        resume_every=args.save_every, cluster=cluster,
    )  # fmt: skip
    print(format_report(manifest))
    _log(f"dataset in {args.out}")
    return 0


def cmd_dataset(args: argparse.Namespace) -> int:
    mib = 2**20
    if args.action == "pack":
        from loosefit.data.pack import pack

        bar = tqdm_bar(f"pack {args.folder}", "file")
        try:
            r = pack(args.folder, args.out, args.piece_mib, args.workers, progress=bar.progress)
        finally:
            bar.close()
        where = str(r.paths[0]) + (f" ... {r.paths[-1].name}" if len(r.paths) > 1 else "")
        print(f"{where}: {r.packed_bytes / mib:.1f} MiB in {len(r.paths)} file(s), "
              f"{r.files} files ({r.clips} clips); {r.ratio:.1f}x smaller than the .npz files "
              f"({r.npz_bytes / mib:.1f} MiB); vertices within {r.max_error * 1e3:.4f} mm of "
              f"the data set's (at most {r.step * 500:g} mm), every other array exact")  # fmt: skip
        return 0
    from loosefit.data.pack import unpack

    bar = tqdm_bar(f"unpack {args.pack}", "file")
    try:
        r = unpack(args.pack, args.dest, progress=bar.progress)
    finally:
        bar.close()
    checked = "the pack's index" if r.indexed else "its manifest"
    _log(f"unpacked {r.files} files ({r.clips} clips) from {len(r.pieces)} file(s) into "
         f"{r.dest}, checked against {checked}")  # fmt: skip
    return 0


def cmd_train(args: argparse.Namespace) -> int:
    import torch

    if args.threads:
        torch.set_num_threads(args.threads)
    world = int(os.environ.get("WORLD_SIZE", "1"))
    if world > 1:  # launched by torchrun: one process of several
        if args.stage not in ("generative", "motion"):
            raise LoosefitInputError("torchrun", "stage", "generative or motion (the stages that "
                                     "train on several processes so far)", args.stage)  # fmt: skip
        import torch.distributed as dist

        if not dist.is_initialized():
            dist.init_process_group("nccl" if args.device.startswith("cuda") else "gloo")
        if args.device.startswith("cuda"):
            args.device = f"cuda:{int(os.environ.get('LOCAL_RANK', '0'))}"
    if args.stage in ("detail", "baseline") and args.precision not in (None, "fp32"):
        raise LoosefitInputError("loosefit train", "--precision", "fp32 for the detail and "
                                 "baseline stages (bf16: generative and motion)",
                                 args.precision)  # fmt: skip
    if args.stage == "baseline" and args.init:
        raise LoosefitInputError("loosefit train", "--init", "a warm start for the generative, "
                                 "motion and detail stages only", args.init)  # fmt: skip
    if args.stage == "motion":
        return _train_motion(args)
    if args.stage == "detail":
        return _train_detail(args)
    if args.stage == "baseline":
        return _train_baseline(args)
    from loosefit.train.generative import TrainGenerativeConfig, train_generative

    cfg = TrainGenerativeConfig.preset(
        args.preset, decoder=args.decoder, epochs=args.epochs, device=args.device,
        max_frames=args.max_frames, batch_size=args.batch_size, lr=args.lr, seed=args.seed,
        precision=args.precision,
    )  # fmt: skip
    cfg.loss = _physics_weights(cfg.loss, args, collision=True)
    cfg.init = args.init
    out = args.out or f"runs/generative-{args.preset}-{cfg.model.decoder}"
    report = train_generative(args.data, out, cfg, log=_log)
    return _train_finish(out, report, "checkpoint")


def _physics_weights(loss, args: argparse.Namespace, collision: bool):
    """A loss config with ``--membrane``, ``--bending``, (generative) ``--collision`` and
    (motion) ``--flare`` (checked as the config checks its weights)."""
    import dataclasses

    given = {n: getattr(args, n, None) for n in ("membrane", "bending", "collision", "flare")}
    given = {n: v for n, v in given.items() if v is not None}
    if "collision" in given and not collision:
        raise LoosefitInputError("loosefit train motion", "--collision",
                                 "no collision weight (the generative stage takes it)",
                                 given["collision"])  # fmt: skip
    if "flare" in given and collision:
        raise LoosefitInputError("loosefit train generative", "--flare",
                                 "no flare weight (the motion stage takes it)",
                                 given["flare"])  # fmt: skip
    return dataclasses.replace(loss, **given)


def _train_finish(out, report: dict, kept: str = "model") -> int:
    """A finished training run: its report, and where the run and its ``kept``.pt are
    (under torchrun, the first process's to say: the others return 0 quietly)."""
    from loosefit.train.common import distributed

    if distributed()[0] > 0:
        return 0
    print(Path(out, "report.md").read_text())
    _log(f"run in {out}; {kept} {Path(out, kept + '.pt')}")
    return 0 if report else 1


def _train_motion(args: argparse.Namespace) -> int:
    from loosefit.train.motion import TrainMotionConfig, train_motion

    if not args.generative:
        raise LoosefitInputError(
            "loosefit train motion", "--generative", "the trained generative model's checkpoint",
            "none",
        )  # fmt: skip
    cfg = TrainMotionConfig.preset(
        args.preset, epochs=args.epochs, device=args.device, max_frames=args.max_frames,
        batch_size=args.batch_size, lr=args.lr, previous=args.previous,
        previous_state=False if args.no_previous_state else None,
        mirror=True if args.mirror else None, joints=args.joints, seed=args.seed,
        precision=args.precision,
    )  # fmt: skip
    cfg.loss = _physics_weights(cfg.loss, args, collision=False)
    cfg.init = args.init
    kind = "ps" if cfg.model.previous_state else "nops"
    out = args.out or f"runs/motion-{args.preset}-{kind}"
    report = train_motion(args.data, args.generative, out, cfg, log=_log)
    return _train_finish(out, report)


def _train_detail(args: argparse.Namespace) -> int:
    from loosefit.train.detail import TrainDetailConfig, train_detail

    if not args.motion:
        raise LoosefitInputError("loosefit train detail", "--motion",
                                 "the trained motion stage's model.pt", "none")  # fmt: skip
    cfg = TrainDetailConfig.preset(
        args.preset, epochs=args.epochs, device=args.device, max_frames=args.max_frames,
        batch_size=args.batch_size, lr=args.lr,
        discriminator=False if args.no_discriminator else None, seed=args.seed,
    )  # fmt: skip
    if args.edge_weight is not None:
        cfg.loss.edge = args.edge_weight
    cfg.init = args.init
    kind = ("full" if cfg.discriminator else "nodisc") + ("-edge" if cfg.loss.edge else "")
    out = args.out or f"runs/detail-{args.preset}-{kind}"
    report = train_detail(args.data, args.motion, out, cfg, args.generative, log=_log)
    return _train_finish(out, report)


def _train_baseline(args: argparse.Namespace) -> int:
    from loosefit.train.baseline import TrainBaselineConfig, train_baseline

    if not args.method:
        raise LoosefitInputError("loosefit train baseline", "--method",
                                 "santesteban or virtual-bones", "none")  # fmt: skip
    cfg = TrainBaselineConfig.preset(
        args.preset, method=args.method, epochs=args.epochs, device=args.device,
        max_frames=args.max_frames, batch_size=args.batch_size, lr=args.lr,
        mirror=True if args.mirror else None, joints=args.joints, bones=args.bones,
        seed=args.seed,
    )  # fmt: skip
    out = args.out or f"runs/baseline-{args.preset}-{args.method}"
    return _train_finish(out, train_baseline(args.data, out, cfg, log=_log))


def _stages(args: argparse.Namespace):
    from loosefit.model.rollout import Stages

    return Stages(detail=not args.no_detail, lengths=not args.no_lengths,
                  collision=not args.no_collision, feedback=args.feedback)  # fmt: skip


def _add_stage_args(p: argparse.ArgumentParser) -> None:
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
    p.add_argument("--feedback", action="store_true",
                   help="feed the garment after detail and collision back as the next frame's "
                   "previous state (default: the decoders' output, as in training)")  # fmt: skip


def _add_runtime_args(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--runtime", default="torch", choices=("torch", "onnx"),
        help="what runs the learned stages (motion stage, detail): torch (PyTorch), or onnx "
        "(onnxruntime: the same garments, faster on one core; pip install 'loosefit[onnx]'; "
        "the graphs are exported in memory at the start, about a second). Edge lengths and "
        "collision handling are the same either way (docs/ENGINE_EXPORT.md)",
    )  # fmt: skip
    p.add_argument(
        "--collision", default="full", choices=("full", "realtime"),
        help="collision handling: full, or realtime (one solve and one round of its last "
        "projection and mending a frame: 1.3-2.2x faster, a little more cloth left within a "
        "millimetre of the skin; docs/BENCHMARKS.md, 'Issue 37')",
    )  # fmt: skip


def _animate_inputs(args: argparse.Namespace) -> None:
    """``animate [CHECKPOINT] MOTION``: without a checkpoint, the pretrained default."""
    from loosefit.api import pretrained_checkpoint

    if len(args.inputs) not in (1, 2):
        raise LoosefitInputError("animate", "arguments", "[CHECKPOINT] MOTION",
                                 f"{len(args.inputs)} arguments: {args.inputs}")  # fmt: skip
    if len(args.inputs) == 2:
        args.checkpoint, args.motion = args.inputs
        return
    args.checkpoint, args.motion = pretrained_checkpoint(), args.inputs[0]
    if not args.checkpoint.is_file():
        raise LoosefitInputError(
            args.checkpoint, "checkpoint", "the pretrained pair of a loosefit clone",
            "no such file", hint="pass a checkpoint: loosefit animate CHECKPOINT MOTION",
        )  # fmt: skip
    _log(f"no checkpoint given: the pretrained default {args.checkpoint}")
    _trained_on_note(args.checkpoint)


def cmd_animate(args: argparse.Namespace) -> int:

    _animate_inputs(args)
    from loosefit.api import motion_for
    from loosefit.inference.animator import load_pipeline
    from loosefit.sequence import AnimatedGarment

    model = load_pipeline(args.checkpoint, args.generative, args.detail)
    stages = _stages(args)
    _physics_note(model, stages)
    avatar = model.avatar()
    if args.frames is not None and args.frames < 1:
        raise LoosefitInputError("--frames", "frames", "at least 1", args.frames)
    motion = motion_for(args.motion, avatar, model.fps, args.frames, args.start_frame, args.seed,
                        retarget=_retarget_config(args))  # fmt: skip
    # the motion's own name (a chain's names all of its parts), safe as a file name
    name = re.sub(r"[^A-Za-z0-9_.-]+", "_", motion.name).strip("._") or "motion"
    out = Path(args.out)
    if out.suffix not in ("", ".npz") and not out.is_dir():
        raise LoosefitInputError("--out", "out", "a .npz file or a folder", str(out))
    path = out if out.suffix == ".npz" else out / f"{name}.npz"
    if args.export:
        from loosefit.export import check_export_path

        check_export_path(args.export)  # before the work, not after
    _log(f"animating {motion.num_frames} frames of '{motion.name}'")
    bar = tqdm_bar("rollout", unit="frame")
    result = model.animate(motion, bar.progress, stages=stages, runtime=args.runtime,
                           collision=args.collision)  # fmt: skip
    bar.close()
    _log(_stage_line(model, stages, result))
    shape = {"rig": avatar.config.rig, "shape": dict(avatar.shape)}
    seq = AnimatedGarment(motion, model.template, result.vertices, shape,
                          f"loosefit model {Path(args.checkpoint).resolve()}")  # fmt: skip
    path.parent.mkdir(parents=True, exist_ok=True)
    seq.save(path)
    _log(f"{_throughput(motion, result)}; wrote {path}")
    if args.export:
        _log_exported(seq.export(args.export))
    if args.render:
        _render(args, avatar, motion, model.template, result.vertices,
                path.with_name(path.stem + "_render"),
                f"{motion.name} (loosefit rollout)")  # fmt: skip
    return 0


def _log_exported(files: list) -> None:
    _log(f"exported {len(files)} file(s): {files[0]}" + (" ..." if len(files) > 1 else ""))


def cmd_export(args: argparse.Namespace) -> int:
    path = Path(args.sequence)
    if path.suffix != ".npz":
        raise LoosefitInputError(path, "<file>", "a sequence .npz (from animate, the API, demo "
                                 "or a data set's sequences/)", "another file")  # fmt: skip
    _log_exported(read_any_sequence(path).export(args.out, body=not args.no_body))
    return 0


def cmd_diagnose(args: argparse.Namespace) -> int:
    """Where and why a clip's cloth goes deeper into the body than the tolerance: a table of
    events, diagnosis.json and renders of the worst frames (loosefit.eval.penetration)."""
    import json

    import torch

    from loosefit.data.format import DatasetReader, write_json_atomic
    from loosefit.dress import collider_arms
    from loosefit.eval.body_regions import body_parts
    from loosefit.eval.penetration import diagnose_clip, format_events
    from loosefit.eval.quality import PENETRATION_TOLERANCE
    from loosefit.inference.animator import arm_collision_of

    source = Path(args.source)
    tolerance = PENETRATION_TOLERANCE if args.tolerance is None else args.tolerance
    if not 0.0 < tolerance < 1.0 or args.top < 0 or args.merge_gap < 0:
        raise LoosefitInputError("loosefit diagnose", "--tolerance, --top, --merge-gap",
                                 "0 < tolerance < 1 m, top >= 0, merge gap >= 0",
                                 f"{tolerance}, {args.top}, {args.merge_gap}")  # fmt: skip
    if source.is_dir():
        if not args.clip:
            raise LoosefitInputError(source, "CLIP", "a clip of the data set after it",
                                     "none", hint="its clips: sequences/*.npz")  # fmt: skip
        seq, name = DatasetReader(source, allow_incomplete=True).read(args.clip), args.clip
        manifest = source / "manifest.json"
    else:
        if args.clip:
            raise LoosefitInputError(source, "CLIP", "no clip after a sequence file", args.clip)
        seq, name = read_any_sequence(source), source.stem
        manifest = source.parent.parent / "manifest.json"  # a data set's sequences/NAME.npz
    arms = {"none": False, "upper": "upper", "all": True}.get(args.arms)
    if args.arms == "auto":  # the simulation's collider: the data set's, else the garment's
        config = json.loads(manifest.read_text()).get("config", {}) if manifest.is_file() else {}
        arms = arm_collision_of(config, collider_arms(seq.garment))
    args.shape = ",".join(f"{k}={v}" for k, v in seq.avatar.get("shape", {}).items())
    avatar = _avatar(args)
    avatar.check_motion(seq.motion)
    with torch.no_grad():
        body = avatar.pose_motion(seq.motion).vertices.float().cpu().numpy()  # (T, Vb, 3)
    parts = body_parts(avatar, arms)
    bar = tqdm_bar("diagnose", unit="frame")
    diag = diagnose_clip(seq.garment_vertices, body, seq.motion.rotations[:, 0], seq.fps, parts,
                         tolerance, args.merge_gap, progress=bar.progress)  # fmt: skip
    bar.close()
    print(f"{name}: {diag.summary()}; arms collide: {arms}")
    print(format_events(diag.events, tolerance))
    out = Path(args.out or f"out/diagnose/{name}")
    out.mkdir(parents=True, exist_ok=True)
    frames = diag.worst_frames(args.top)
    renders = _render_worst(args, diag, parts, seq, body, avatar.faces.cpu().numpy(), name, out,
                            frames) if frames else []  # fmt: skip
    report = {"clip": name, "source": str(source), "arm_collision": arms, **diag.to_json(),
              "renders": [str(p) for p in renders]}  # fmt: skip
    write_json_atomic(out / "diagnosis.json", report)
    _log(f"wrote {out / 'diagnosis.json'}")
    return 0


def _render_worst(args, diag, parts, seq, body, body_faces, name: str, out: Path,
                  frames: list[int]) -> list[Path]:  # fmt: skip
    """``diagnose``'s PNGs: each of ``frames`` whole and close up (loosefit.render.closeup)."""
    from PIL import Image

    from loosefit.eval.penetration import closeup
    from loosefit.render.closeup import render_penetration
    from loosefit.render.renderer import RenderConfig, Renderer

    pen, paths = diag.penetrations, []
    config = RenderConfig(width=args.size, height=args.size, labels=False, frame_counter=False)
    with Renderer(config) as renderer:
        for rank, t in enumerate(frames, 1):
            root = seq.motion.root_translation[t]
            view = closeup(pen, parts, t, seq.garment.num_vertices, root)
            title = (f"{name} frame {t} ({t / seq.fps:.2f} s): {int(view.deep.sum())} vertices "
                     f"deeper than {1000 * pen.tolerance:.0f} mm, deepest "
                     f"{100 * pen.max_depth[t]:.1f} cm, in the {view.regions[0]}")  # fmt: skip
            image = render_penetration(
                body[t], body_faces, seq.garment_vertices[t], seq.garment.faces, view.deep,
                view.target, view.direction, view.hidden, ~parts.colliding, size=args.size,
                title=title, hidden_label=", ".join(view.regions), renderer=renderer,
            )  # fmt: skip
            paths.append(out / f"worst{rank}_frame{t:05d}.png")
            Image.fromarray(image).save(paths[-1], optimize=True)
            _log(f"wrote {paths[-1]}")
    return paths


def _trained_on_note(path: Path) -> None:
    """Say what a packaged set was trained on (the motion it knows)."""
    from loosefit.api import trained_on

    _log(f"model {Path(path).parent.name}: trained on {trained_on(path)}")


def _physics_note(model, stages) -> None:
    """Say which physics terms (issue 34) a model's stages were trained without."""
    missing = getattr(model, "missing_physics_terms", ())
    if missing:
        fix = ("the edge-length stage restores them" if stages.lengths
               else "--no-lengths leaves them so")  # fmt: skip
        _log(f"this model was trained without the physics terms {', '.join(missing)} "
             f"(issue 34): its decoders give edges shorter than rest; {fix}")  # fmt: skip


def _throughput(motion, result) -> str:
    """How long a rollout took, apart from the clip's own frame rate: "animated 274 frames
    of a 30 fps clip (9.1 s) in 55.0 s (5 frames per second)"."""
    extra = result.frames - motion.num_frames
    preroll = f", {extra} frames of preroll more" if extra > 0 else ""
    return (
        f"animated {motion.num_frames} frames of a {motion.fps:g} fps clip "
        f"({motion.num_frames / motion.fps:.1f} s) in {result.seconds:.1f} s "
        f"({result.frames_per_second:.0f} frames per second{preroll})"
    )


def _stage_line(model, stages, result) -> str:
    """What ran after the decoders, and what collision handling did."""
    from loosefit.eval.quality import PENETRATION_TOLERANCE

    ran = ["motion"]
    if stages.detail and model.detail is not None:
        ran.append("detail")
    elif stages.detail:
        ran.append("(no detail stage in this checkpoint)")
    if hasattr(model, "restorer") and model.restorer(stages) is not None:  # baselines: none
        ran.append("edge lengths")
    if stages.collision:
        ran.append("collision")
    line = "stages: " + " -> ".join(ran)
    if result.collisions:
        before = sum(c["inside_before"] > 0 for c in result.collisions)
        after = [c for c in result.collisions if c["inside_after"] > 0]
        deep = sum(c["depth_after"] > PENETRATION_TOLERANCE for c in result.collisions)
        whole = model.collision.whole_body or model.arm_collision is True
        body = "the body (arms and hands included)" if whole else "the body (without its arms)"
        line += (f"; collision handling: {before} of {len(result.collisions)} frames had cloth "
                 f"inside {body}, {len(after)} still do, {deep} deeper than "
                 f"{PENETRATION_TOLERANCE * 1000:.0f} mm")  # fmt: skip
        if after:
            worst = max(range(len(result.collisions)),
                        key=lambda k: result.collisions[k]["depth_after"])  # fmt: skip
            line += (f" (deepest: frame {worst}, "
                     f"{100 * result.collisions[worst]['depth_after']:.2f} cm)")  # fmt: skip
    return line


def cmd_evaluate(args: argparse.Namespace) -> int:
    from loosefit.data.format import DatasetReader
    from loosefit.eval.report import write_rollout_report
    from loosefit.eval.rollouts import evaluate_rollouts
    from loosefit.inference.animator import load_pipeline

    model = load_pipeline(args.checkpoint, args.generative, args.detail)
    if len(args.data) == 1 and Path(args.data[0]).is_dir():
        reader = DatasetReader(args.data[0])
        where = str(Path(args.data[0]).resolve())
    else:  # sequences: the ground truth of each motion
        reader = {Path(f).stem: read_any_sequence(f) for f in args.data}
        where = [str(Path(f).resolve()) for f in args.data]
    try:
        horizons = tuple(int(h) for h in args.horizons.split(","))
    except ValueError:
        raise LoosefitInputError("--horizons", "horizons", "comma-separated frame counts",
                                 repr(args.horizons)) from None  # fmt: skip
    result = evaluate_rollouts(model, reader, args.split, horizons, surface=not args.rmse_only,
                               max_frames=args.max_frames, stages=_stages(args))  # fmt: skip
    result["checkpoint"] = str(Path(args.checkpoint).resolve())
    result["dataset"] = where
    write_rollout_report(result, args.out, f"Rollouts of {Path(args.checkpoint).parent.name}")
    print(Path(args.out, "evaluation.md").read_text())
    _log(f"wrote {args.out}/evaluation.{{md,csv,json}} and rmse_per_frame.png")
    return 0


def cmd_package(args: argparse.Namespace) -> int:
    from loosefit.inference.package import package_detail, package_model

    files = list(package_model(args.checkpoint, args.out, args.generative))
    if args.detail:
        files.append(package_detail(args.detail, args.out))
    for f in files:
        _log(f"wrote {f} ({f.stat().st_size / 1e6:.1f} MB)")
    return 0


def cmd_export_model(args: argparse.Namespace) -> int:
    import json

    from loosefit.api import pretrained_checkpoint
    from loosefit.inference.animator import load_pipeline
    from loosefit.inference.onnx_export import OnnxExportConfig, export_onnx

    checkpoint = Path(args.checkpoint) if args.checkpoint else pretrained_checkpoint()
    model = load_pipeline(checkpoint, args.generative, args.detail)
    config = OnnxExportConfig(opset=args.opset, detail=not args.no_detail,
                              check=not args.no_check)  # fmt: skip
    _log(f"exporting {checkpoint} to ONNX (opset {config.opset})")
    onnx_path, json_path, obj_path = export_onnx(model, args.out, config)
    _log(
        f"wrote {onnx_path} ({onnx_path.stat().st_size / 1e6:.1f} MB), {json_path} and "
        f"{obj_path} (the garment's mesh)"
    )
    check = json.loads(json_path.read_text()).get("check")  # what the export recorded
    if check is None:
        _log("not checked against PyTorch (--no-check)")
    else:
        _log(f"checked: onnxruntime {check['onnxruntime']} equals PyTorch within "
             f"{check['max_difference_m']:.2g} m over {check['frames']} frames (the rest pose, "
             f"then a bent one; {config.tolerance:g} m allowed)")  # fmt: skip
    return 0


def _frame_ref(text: str, names: list[str], source: str) -> tuple[str, int]:
    name, _, frame = text.rpartition(":")
    if not name or not frame.isdigit():
        raise LoosefitInputError(source, "frame", "CLIP:FRAME, e.g. 'dance_000:40'", repr(text))
    if name not in names:
        raise LoosefitInputError(source, "clip", f"one of {names}", repr(name))
    return name, int(frame)


def cmd_interpolate(args: argparse.Namespace) -> int:
    import numpy as np
    import torch

    from loosefit.data.format import DatasetReader
    from loosefit.inference.checkpoints import load_generative
    from loosefit.model.motion_features import garment_in_root_frame
    from loosefit.render.clip import render_clip
    from loosefit.render.renderer import RenderConfig, RenderMesh

    reader = DatasetReader(args.data)
    model, _ = load_generative(args.checkpoint, reader.template)
    posed = []
    for which, text in (("--a", args.a), ("--b", args.b)):
        name, f = _frame_ref(text, reader.split("all"), which)
        seq = reader.read(name)
        if not 0 <= f < seq.num_frames:
            raise LoosefitInputError(
                which, "frame", f"a frame of '{name}' (0..{seq.num_frames - 1})", f
            )
        posed.append(
            garment_in_root_frame(seq.motion.slice(f, f + 1), seq.garment_vertices[f : f + 1])
        )
    with torch.no_grad():
        mu, _ = model.encode(torch.cat(posed))
        alpha = torch.linspace(0, 1, args.steps)[:, None]
        garments = model.decode((1 - alpha) * mu[0] + alpha * mu[1])["vertices"].numpy()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    np.savez(out / "interpolation.npz", vertices=garments, faces=reader.template.faces,
             alpha=alpha[:, 0].numpy())  # fmt: skip
    _log(f"wrote {out / 'interpolation.npz'} ({args.steps} garments, root frame)")
    # root frame -> standing on the floor, root joint at its rest height
    lifted = garments + np.array([0.0, 0.0, float(reader.body.get("floor_height", 0.9))])
    scene = [RenderMesh(reader.template.faces, lifted, "garment", name="garment")]
    config = RenderConfig(width=args.size, height=args.size, views=("front", "side"),
                          follow=False)  # fmt: skip
    result = render_clip(scene, out, fps=4.0, config=config, png_every=1,
                         title=f"latent interpolation {args.a} -> {args.b}")  # fmt: skip
    _log(f"wrote {result.video}" + (f" and {result.sheet}" if result.sheet else ""))
    return 0


def cmd_reconstruct(args: argparse.Namespace) -> int:
    import torch

    from loosefit.data.format import DatasetReader
    from loosefit.eval.metrics import rmse
    from loosefit.inference.checkpoints import load_generative
    from loosefit.model.motion_features import (
        from_root_frame,
        garment_in_root_frame,
        motion_root_frames_of,
    )
    from loosefit.sequence import AnimatedGarment

    reader = DatasetReader(args.data)
    model, _ = load_generative(args.checkpoint, reader.template)
    name = args.clip or reader.split("test")[0]
    seq = reader.read(name)
    avatar, motion, garment = _stored_clip(args, reader.body.get("shape", {}), seq.motion,
                                           seq.garment_vertices)  # fmt: skip
    H, p = motion_root_frames_of(motion)
    with torch.no_grad():
        rec = model.reconstruct_all(garment_in_root_frame(motion, garment), 64)
        world = from_root_frame(rec, H, p).numpy()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    AnimatedGarment(motion, reader.template, world, reader.avatar,
                    f"generative reconstruction {Path(args.checkpoint).resolve()}"
                    ).save(out / "reconstruction.npz")  # fmt: skip
    _log(f"{name}: {len(world)} frames, RMSE {100 * rmse(world, garment):.2f} cm; wrote "
         f"{out / 'reconstruction.npz'} (a sequence, as render --sequence reads)")  # fmt: skip
    _render(args, avatar, motion, reader.template, world, out,
            f"{name}: generative reconstruction")  # fmt: skip
    return 0


def cmd_view(args: argparse.Namespace) -> int:
    """Sequences (and a data set's clip) in the browser viewer, served until Ctrl-C."""
    from loosefit.view.scene import read_sequences

    seqs, labels, sources = read_sequences(args.sequences, args.data, args.clip)
    _serve(seqs, labels, sources, args)
    return 0


def _serve(seqs, labels, sources, args) -> None:
    """Pose the bodies, start the viewer, print its URL and serve until interrupted."""
    from loosefit.view import ViewerConfig, view

    config = ViewerConfig(host=args.host, port=args.port, colouring=args.colour,
                          layout="overlaid" if args.overlay else "side by side",
                          reference=args.reference, play=not args.paused,
                          pixel_ratio=args.pixel_ratio)  # fmt: skip
    config.validate(len(seqs))  # before minutes of posing
    frames = sum(s.num_frames for s in seqs)
    _log(f"{len(seqs)} sequence(s), {seqs[0].num_frames} frames each: posing the bodies")
    bar = tqdm_bar("pose", unit="frame")
    t = time.perf_counter()
    viewer = view(seqs, labels, config, sources, progress=bar.progress)
    bar.close()
    moved = f" (port {args.port} is in use)" if viewer.port != args.port else ""
    _log(f"ready in {time.perf_counter() - t:.1f} s ({frames} frames)")
    print(f"loosefit viewer: {viewer.url}{moved}  (Ctrl-C to stop)", flush=True)
    viewer.wait()


def build_parser() -> argparse.ArgumentParser:
    from loosefit.body.bvh import BVH_UNITS  # numpy only: the parser stays quick to build

    parser = argparse.ArgumentParser(prog="loosefit", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("demo", help="the main job: the pretrained model animates its skirt on "
                       "a 20 s dance (video, USD, PC2); --physics simulates instead")  # fmt: skip
    p.add_argument("--out", default="out/demo", help="output folder")
    p.add_argument("--motion", default=None,
                   help="procedural move, dance:SECONDS, or a file (default: dance:20; with "
                   "--physics: spin)")  # fmt: skip
    p.add_argument(
        "--max-frames",
        type=int,
        default=None,
        help="frames of the motion to use (default: all; with --physics: 90)",
    )
    p.add_argument("--start-frame", type=int, default=0, help="first frame of the motion to use")
    mode = p.add_mutually_exclusive_group()
    mode.add_argument(
        "--physics",
        action="store_true",
        help="simulate the skirt with Newton's VBD solver (minutes) instead",
    )
    mode.add_argument("--no-physics", action="store_true", help="carry the skirt rigidly instead")
    p.add_argument("--checkpoint", default=None,
                   help="a model to animate with (default: the pretrained set)")  # fmt: skip
    _add_runtime_args(p)
    p.add_argument("--sim-device", default="cpu", help="warp device for the simulation")
    p.add_argument("--garment", default=None,
                   help="--physics/--no-physics: skirt style (aline, flared, circle) or an OBJ "
                   "(default flared)")  # fmt: skip
    p.add_argument("--resolution", default="cpu", choices=("cpu", "paper"))
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--fps", type=float, default=30.0)
    _add_bvh_args(p, BVH_UNITS)
    _add_avatar_args(p)
    _add_render_args(p)
    p.add_argument(
        "--view",
        action="store_true",
        help="then open the result in the browser viewer (as loosefit view)",
    )
    _add_view_args(p)
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("render", help="render a motion or a saved sequence to MP4 and PNG")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--motion", help="a .bvh, .gltf/.glb or .npz (loosefit or SMPL) motion, "
                     "or a procedural move name")  # fmt: skip
    src.add_argument("--sequence", help="a sequence .npz (animate, the API, demo, a dataset)")
    src.add_argument("--dataset", help="a dataset folder written by loosefit simulate")
    p.add_argument("--clip", default=None, help="with --dataset: the clip (default: the first)")
    p.add_argument(
        "--garment", default="none", help="with --motion: a skirt style, an .obj or none"
    )
    p.add_argument("--out", default="out/render", help="output folder")
    p.add_argument("--start-frame", type=int, default=0, help="first frame to render (0-based)")
    p.add_argument("--max-frames", type=int, default=None, help="render at most this many frames")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--fps", type=float, default=30.0)
    _add_bvh_args(p, BVH_UNITS)
    _add_avatar_args(p)
    _add_render_args(p, views="front,side")
    p.set_defaults(func=cmd_render)

    p = sub.add_parser("simulate", help="simulate a garment dataset with Newton (resumable)")
    p.add_argument("--preset", default="demo",
                   help="tiny, demo, salsa, salsa-speed, salsa-speeds, dance, paper, "
                   "dress-tiny or dress")  # fmt: skip
    p.add_argument("--config", default=None, metavar="FILE",
                   help="a data set configuration (.yaml, .yml or .toml) instead of a preset; "
                   "--write-config writes one to start from")  # fmt: skip
    p.add_argument(
        "--write-config",
        default=None,
        metavar="FILE",
        help="write the configuration (a preset's, with the options below) and stop",
    )
    p.add_argument("--garment", default=None,
                   help="aline, flared, circle, dress, dress-strapless, or a garment file "
                   "(.obj, .gltf, .glb; see loosefit garment) instead of the preset's")  # fmt: skip
    p.add_argument("--resolution", default="cpu", choices=("cpu", "paper"),
                   help="with a parametric --garment")  # fmt: skip
    p.add_argument("--motions", default=None, metavar="FOLDER_OR_SPECS",
                   help="a folder of BVH files, or comma-separated motions (files, moves, "
                   "dance:SECONDS, mirror:..., speed:F:..., A+B), one clip each")  # fmt: skip
    p.add_argument(
        "--test",
        nargs="+",
        default=None,
        metavar="NAME",
        help="the clips held out (their names: file stems, or the specs' names)",
    )
    _add_import_args(p)
    p.add_argument("--shape", default="",
                   help="the avatar's body as anny phenotypes in [0, 1], e.g. "
                   "'weight=0.7,height=0.6' (a garment --fit to one: its shape)")  # fmt: skip
    p.add_argument("--out", default=None, help="dataset folder (default datasets/PRESET)")
    p.add_argument(
        "--bvh",
        default=None,
        help="salsa, dance, paper: the salsa folder of BVH clips "
        "(dance: with cmu-ballet beside it)",
    )
    p.add_argument("--workers", type=int, default=2,
                   help="parallel simulations (--ray: the CPUs of a Ray instance it starts "
                   "here when none runs)")  # fmt: skip
    p.add_argument("--ray", nargs="?", const="", default=None, metavar="ADDRESS",
                   help="simulate every clip as a task on a Ray cluster: the head's HOST:PORT "
                   "(`ray start --head` prints it), or none: RAY_ADDRESS, the cluster of this "
                   "machine, else a new one here; --out on storage every node shares "
                   "(docs/CLUSTER.md; pip install 'loosefit[cluster]')")  # fmt: skip
    p.add_argument("--save-every", type=int, default=50, metavar="FRAMES",
                   help="frames between the saves of a clip's state, from which a killed run "
                   "goes on")  # fmt: skip
    p.add_argument(
        "--batch",
        type=int,
        default=1,
        metavar="K",
        help="clips simulated at once as worlds of one model (a GPU: 16-64)",
    )
    p.add_argument("--device", default=None, help="warp device: cpu or cuda:0")
    p.add_argument("--max-frames", type=int, default=None, help="frames kept per clip")
    p.add_argument(
        "--keep-poses",
        action="store_true",
        help="simulate the motion exactly as captured: do not turn a limb that "
        "passes into the body out of it (unfold.enabled: false)",
    )
    p.add_argument("--reuse", default=None, metavar="FOLDER",
                   help="take the clips this dataset shares with the one in FOLDER (simulated "
                   "alike) instead of simulating them again")  # fmt: skip
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser("dataset", help="pack a data set small enough to share, or unpack one")
    dsub = p.add_subparsers(dest="action", required=True)
    d = dsub.add_parser("pack", help="a data set folder into one file or numbered pieces "
                        "(garment vertices to 0.02 mm, all else exact), with an index of "
                        "sizes and sha256")  # fmt: skip
    d.add_argument("folder", help="the data set folder (manifest.json, template.npz, sequences/)")
    d.add_argument("out", help="the pack's file (with --piece-mib: OUT.000, OUT.001, ...)")
    d.add_argument("--piece-mib", type=float, default=None, metavar="N",
                   help="cut the pack into pieces of at most N MiB")  # fmt: skip
    d.add_argument("--workers", type=int, default=1, help="processes coding the clips")
    d.set_defaults(func=cmd_dataset)
    d = dsub.add_parser("unpack", help="a pack into a data set folder, verified before it "
                        "appears")  # fmt: skip
    d.add_argument("pack", help="the pack's file, a folder of its pieces, or their common "
                   "prefix (e.g. ../shared/datasets/dance.lfz.)")  # fmt: skip
    d.add_argument("dest", help="the data set folder to make (new or empty)")
    d.set_defaults(func=cmd_dataset)

    p = sub.add_parser("train", help="train a learned stage (resumable)")
    p.add_argument(
        "stage",
        choices=("generative", "motion", "detail", "baseline"),
        help="generative: the garment VAE (3.2); motion: the motion encoder (3.3); detail: "
        "the detail enhancement module (3.4) on a trained motion stage's rollouts; baseline: "
        "one of the paper's baselines (--method)",
    )
    p.add_argument(
        "--method",
        default=None,
        choices=("santesteban", "virtual-bones"),
        help="baseline: Santesteban et al. 2019 (skinned to the body, GRU displacements, "
        "push-out) or Pan et al. 2022 (virtual bones from a skinning decomposition)",
    )
    p.add_argument("--bones", type=int, default=None, help="baseline virtual-bones: bones")
    p.add_argument("--generative", default=None, help="motion: the generative checkpoint")
    p.add_argument("--motion", default=None, help="detail: the motion stage's model.pt")
    p.add_argument(
        "--no-discriminator",
        action="store_true",
        help="detail: the ablation without the multi-scale discriminator (Table 2's middle row)",
    )
    p.add_argument(
        "--edge-weight",
        type=float,
        default=None,
        help="detail: weight of an L1 edge-length term added to Eq. 13 (default 0, the paper's)",
    )
    p.add_argument(
        "--no-previous-state",
        action="store_true",
        help="motion: the 'w/o ps' ablation (no previous garment input)",
    )
    p.add_argument(
        "--previous",
        default=None,
        choices=("scheduled", "teacher"),
        help="motion: previous states by scheduled sampling (default) or ground truth",
    )
    p.add_argument(
        "--mirror",
        action="store_true",
        help="motion, baseline: also train on every clip mirrored left-right (twice the data, no "
        "simulation; the garment must be mirror-symmetric)",
    )
    p.add_argument(
        "--joints",
        default=None,
        choices=("all", "lower"),
        help="motion, baseline: the joints whose rotations the network sees: all (default) or "
        "lower "
        "(spine and legs, what moves the skin a skirt touches)",
    )
    p.add_argument("--data", default="datasets/demo", help="a dataset folder")
    p.add_argument("--preset", default="cpu", help="cpu (about 20 CPU minutes) or full (GPU)")
    p.add_argument("--decoder", default="decomposed", help="generative: decomposed, vertex or ssdr")
    p.add_argument("--out", default=None, help="run folder (default runs/generative-...)")
    p.add_argument("--epochs", type=int, default=None)
    p.add_argument("--batch-size", type=int, default=None)
    p.add_argument("--lr", type=float, default=None)
    p.add_argument("--max-frames", type=int, default=None, help="frames per clip")
    p.add_argument("--device", default="cpu", help="torch device")
    p.add_argument(
        "--precision",
        default=None,
        choices=("fp32", "bf16"),
        help="generative, motion: the networks' forward pass in fp32 (default) or bf16 "
        "(autocast; losses and optimiser stay fp32)",
    )
    p.add_argument("--seed", type=int, default=None, help="training seed (default 0)")
    for name, what in (
        ("membrane", "edge lengths against rest"),
        ("bending", "dihedral angles against rest"),
        ("collision", "cloth outside the whole body; generative only"),
    ):
        p.add_argument(f"--{name}", type=float, default=None, metavar="W",
                       help=f"generative, motion: weight of the {name} term ({what}; "
                       "issue 34; default 0)")  # fmt: skip
    p.add_argument("--flare", type=float, default=None, metavar="W",
                   help="motion: weight of the hem-flare term (the hem's mean distance "
                   "from the root's vertical axis against the simulation's; issue 34; "
                   "default 0)")  # fmt: skip
    p.add_argument("--init", default=None, metavar="CHECKPOINT",
                   help="generative, motion, detail: start from this checkpoint's weights "
                   "(a run's or a packaged set's, same garment and configuration): "
                   "fine-tuning")  # fmt: skip
    p.add_argument("--threads", type=int, default=0, help="torch CPU threads (0: default)")
    p.set_defaults(func=cmd_train)

    p = sub.add_parser("animate", help="animate the garment on a motion with a trained model")
    p.add_argument(
        "inputs", nargs="+", metavar="[CHECKPOINT] MOTION",
        help="a motion run's model.pt or checkpoint.pt (default: the pretrained set in "
        "checkpoints/dance), then a .bvh, .gltf/.glb or .npz (loosefit or SMPL) motion, a "
        "procedural move, or dance:SECONDS "
        "(mirror:MOTION mirrors one left-right; A+B plays one after another)",
    )  # fmt: skip
    _add_generative_arg(p)
    p.add_argument(
        "--frames",
        type=int,
        default=None,
        help="frames to animate (longer than the motion: it plays again)",
    )
    p.add_argument("--start-frame", type=int, default=0)
    p.add_argument("--out", default="out/animate",
                   help="the sequence .npz to write, or a folder for MOTION.npz")  # fmt: skip
    p.add_argument("--render", action="store_true", help="also render a video and PNGs")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--export", default=None, metavar="PATH",
                   help="also export garment and body: .usd/.usdc/.usda (USD), .pc2 (point "
                   "caches + OBJ), or a folder (OBJ per frame)")  # fmt: skip
    _add_bvh_args(p, BVH_UNITS)
    _add_stage_args(p)
    _add_runtime_args(p)
    _add_render_args(p, views="front,side")
    p.set_defaults(func=cmd_animate)

    p = sub.add_parser(
        "view", help="sequences in a 3D viewer in the browser (pip install 'loosefit[viewer]')",
        description="Serve sequences of one garment and motion in a 3D viewer in the browser "
        "(viser): the bodies and garments side by side or overlaid, each shown or hidden; "
        "play, pause, a frame slider, the speed, a camera that follows; the garment coloured "
        "by its distance to a reference sequence, its edge strain or its depth inside the "
        "body, with the frame's RMSE. Nothing needs a display: open the printed URL in any "
        "browser (from another machine: ssh -L PORT:localhost:PORT). Sequences opened "
        "together share one timeline and are refused (naming both) unless they have the "
        "same garment, frame count and frame rate; view others one at a time.",
    )  # fmt: skip
    p.add_argument("sequences", nargs="*", metavar="SEQUENCE",
                   help="sequence .npz files: animate's, the API's save(), demo's "
                   "sequence.npz, a data set's sequences/NAME.npz")  # fmt: skip
    p.add_argument(
        "--data",
        default=None,
        metavar="DATASET",
        help="a data set folder: with --clip, its simulated clip (shown first)",
    )
    p.add_argument("--clip", default=None, metavar="NAME", help="the clip of --data")
    _add_view_args(p)
    p.set_defaults(func=cmd_view)

    p = sub.add_parser("export", help="a sequence to USD, PC2 point caches or an OBJ sequence")
    p.add_argument(
        "sequence",
        help="a sequence .npz (from animate, the API's save(), demo's sequence.npz, or a "
        "dataset's sequences/NAME.npz)",
    )
    p.add_argument("out", help=".usd, .usdc, .usda, .pc2, or a folder for an OBJ sequence")
    p.add_argument("--no-body", action="store_true", help="the garment only")
    p.set_defaults(func=cmd_export)

    p = sub.add_parser("diagnose", help="where and why a clip's cloth goes deep inside the body")
    p.add_argument("source", help="a data set folder (then CLIP), or a sequence .npz")
    p.add_argument("clip", nargs="?", default=None, help="with a data set: the clip's name")
    p.add_argument("--out", default=None, help="folder (default out/diagnose/CLIP)")
    p.add_argument("--top", type=int, default=3, help="render this many worst frames")
    p.add_argument("--tolerance", type=float, default=None, metavar="M",
                   help="metres of depth that count (default 0.005, as simulate's)")  # fmt: skip
    p.add_argument("--merge-gap", type=int, default=0,
                   help="frames without penetration that still join two events")  # fmt: skip
    p.add_argument("--arms", default="auto", choices=("auto", "none", "upper", "all"),
                   help="the collider's arms (default: the data set's cloth config, else "
                   "the garment's)")  # fmt: skip
    p.add_argument("--size", type=int, default=360, help="pixels per rendered view")
    p.add_argument("--device", default="cpu", help="torch device for posing")
    p.set_defaults(func=cmd_diagnose)

    p = sub.add_parser("evaluate", help="roll out held-out clips and compare with the simulation")
    p.add_argument("--checkpoint", required=True, help="a motion run's model.pt or checkpoint.pt")
    _add_generative_arg(p)
    p.add_argument("--data", nargs="+", default=["datasets/salsa"],
                   help="a dataset folder, or sequence .npz files (the ground truth of their "
                   "motions, e.g. from loosefit.simulate)")  # fmt: skip
    p.add_argument("--split", default="test", help="with a dataset: train, test or all")
    p.add_argument("--horizons", default="100,500,1200", help="frames for iter-N errors")
    p.add_argument("--max-frames", type=int, default=None, help="roll out at most this many")
    p.add_argument("--rmse-only", action="store_true", help="skip Hausdorff and STED (faster)")
    p.add_argument("--out", default="out/evaluate")
    _add_stage_args(p)
    p.set_defaults(func=cmd_evaluate)

    p = sub.add_parser(
        "package", help="a trained model's stages in one folder, half precision, to share"
    )
    p.add_argument("checkpoint", help="a motion run's model.pt or checkpoint.pt")
    _add_generative_arg(p)
    p.add_argument("--detail", default=None, help="also this detail stage's model.pt")
    p.add_argument("--out", required=True,
                   help="folder for generative.pt, motion.pt (and detail.pt)")  # fmt: skip
    p.set_defaults(func=cmd_package)

    p = sub.add_parser("export-model", help="the learned runtime as ONNX for an engine, with "
                       "a JSON of what its inputs mean (docs/ENGINE_EXPORT.md)")  # fmt: skip
    p.add_argument(
        "out",
        help="the .onnx file to write (OUT.json and the garment's OUT.obj are written beside it)",
    )
    p.add_argument("--checkpoint", default=None,
                   help="a motion-stage, detail or packaged checkpoint (default: the "
                   "pretrained set)")  # fmt: skip
    _add_generative_arg(p)
    p.add_argument("--detail", default=None, help="a detail stage's checkpoint to include")
    p.add_argument("--no-detail", action="store_true", help="leave the detail stage out")
    p.add_argument("--opset", type=int, default=17, help="ONNX opset (16-20)")
    p.add_argument("--no-check", action="store_true",
                   help="skip running a frame through onnxruntime against PyTorch")  # fmt: skip
    p.set_defaults(func=cmd_export_model)

    p = sub.add_parser("reconstruct", help="encode and decode a clip with a generative model")
    p.add_argument("--checkpoint", required=True, help="a generative run's checkpoint.pt")
    p.add_argument("--data", default="datasets/demo", help="a dataset folder")
    p.add_argument("--clip", default=None, help="the clip (default: the first test clip)")
    p.add_argument("--max-frames", type=int, default=None)
    p.add_argument("--out", default="out/reconstruct")
    _add_avatar_args(p)
    _add_render_args(p, views="front,side")
    p.set_defaults(func=cmd_reconstruct)

    p = sub.add_parser("interpolate", help="garments along a line between two latent codes")
    p.add_argument("--checkpoint", required=True, help="a generative run's checkpoint.pt")
    p.add_argument("--data", default="datasets/demo", help="the dataset holding the two frames")
    p.add_argument("--a", required=True, help="CLIP:FRAME of the first garment")
    p.add_argument("--b", required=True, help="CLIP:FRAME of the second garment")
    p.add_argument("--steps", type=int, default=8)
    p.add_argument("--out", default="out/interpolation")
    p.add_argument("--size", type=int, default=384)
    p.set_defaults(func=cmd_interpolate)

    p = sub.add_parser("motion", help="convert a BVH, glTF or SMPL file or a procedural move "
                       "to a motion .npz")  # fmt: skip
    p.add_argument("spec", help="a .bvh, .gltf/.glb or SMPL .npz file, a procedural move name, "
                   "or dance:SECONDS")  # fmt: skip
    p.add_argument("--out", required=True, help="output .npz")
    p.add_argument("--fps", type=float, default=30.0)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--max-frames", type=int, default=None)
    _add_bvh_args(p, BVH_UNITS)
    _add_avatar_args(p)
    p.set_defaults(func=cmd_motion)

    p = sub.add_parser("inspect-motion", help="how a motion capture file (BVH, glTF, SMPL "
                       ".npz) would be read: its joints, "
                       "the avatar joint each drives and why, the dancer's height, units, "
                       "frames")  # fmt: skip
    p.add_argument("file", help="a .bvh, .gltf/.glb or SMPL .npz file")
    _add_bvh_args(p, BVH_UNITS)
    p.add_argument("--sheet", metavar="PNG", default=None,
                   help="also retarget it onto the avatar, run the pose check, and write a "
                   "contact sheet: the capture's skeleton (sticks) beside the avatar at a few "
                   "frames")  # fmt: skip
    p.add_argument("--sheet-frames", type=int, default=6, help="frames on the --sheet")
    p.add_argument(
        "--write-joint-map",
        metavar="YAML",
        default=None,
        help="write a joint map file filled in with what was matched (or, when "
        "nothing could be, guessed by name), to correct and pass as --joint-map",
    )
    _add_avatar_args(p)
    p.set_defaults(func=cmd_inspect_motion)

    p = sub.add_parser("garment", help="make a skirt or a dress, or import a garment file onto "
                       "the avatar")  # fmt: skip
    p.add_argument("source", help="aline, flared, circle, dress, dress-strapless, or a garment "
                   "file (.obj, .gltf, .glb) in any units and axes")  # fmt: skip
    p.add_argument("--out", default="out/garment", help="output folder")
    p.add_argument("--resolution", default="cpu", choices=("cpu", "paper"))
    p.add_argument("--length", type=float, default=None, help="skirt or dress length, metres")
    _add_import_args(p)
    p.add_argument("--fit", action="store_true",
                   help="a garment made for another body: push it out of the avatar (keeping "
                   "its shape, Eq. 16) and drape it there, instead of refusing it; with "
                   "--shape auto, first pick the anny body it fits best")  # fmt: skip
    p.add_argument("--settle", type=float, default=0.5,
                   help="with --fit: seconds of drape on the avatar standing still")  # fmt: skip
    _add_avatar_args(p)
    p.set_defaults(func=cmd_garment)
    return parser


def _add_import_args(p: argparse.ArgumentParser) -> None:
    """How a garment file is read and placed (loosefit.dress.import_garment)."""
    p.add_argument("--units", default=None, choices=("m", "dm", "cm", "mm", "in"),
                   help="a garment file's unit (default: guessed from its size)")  # fmt: skip
    p.add_argument(
        "--up",
        default=None,
        choices=("z", "y", "-z", "-y"),
        help="a garment file's up axis (default: guessed from its openings)",
    )
    p.add_argument("--kind", default=None, choices=("skirt", "dress"),
                   help="skirt (waistband at the natural waist) or dress (on the shoulders, or "
                   "its top band at the chest); default: a dress if it has straps")  # fmt: skip
    p.add_argument(
        "--offset",
        default=None,
        metavar="X,Y,Z",
        help="metres to move a garment file by after placement",
    )
    p.add_argument("--attach", default="auto",
                   help="what the simulation holds: auto (the waistband, a strapless top band, "
                   "or straps over the shoulders), top (the top opening), or a text file of "
                   "vertex indices")  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except LoosefitInputError as exc:
        print(f"loosefit: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
