"""``loosefit export`` (a sequence to USD, PC2 or OBJ files) and ``loosefit export-model``
(the learned runtime as ONNX for a game engine)."""

from __future__ import annotations

import argparse
from pathlib import Path

from loosefit.cli.common import (
    add_export_format_args,
    add_generative_arg,
    export_config,
    log,
    log_exported,
)


def add_export_parser(sub) -> None:
    p = sub.add_parser(
        "export", help="a sequence to USD, Alembic, glTF, PC2 point caches or an OBJ sequence"
    )
    p.add_argument(
        "sequence",
        help="a sequence .npz (from animate, the API's save(), demo's sequence.npz, or a "
        "dataset's sequences/NAME.npz)",
    )
    p.add_argument(
        "out",
        help=".usd, .usdc, .usda (USD, the body skinned), .abc (Alembic), .glb (glTF, the body "
        "skinned), .pc2 (point caches + OBJ), or a folder for an OBJ sequence",
    )
    p.add_argument("--no-body", action="store_true", help="the garment only")
    add_export_format_args(p)
    p.set_defaults(func=run_export)


def add_export_model_parser(sub) -> None:
    p = sub.add_parser(
        "export-model",
        help="the learned runtime as ONNX for an engine, with "
        "a JSON of what its inputs mean (docs/use/ENGINE_EXPORT.md)",
    )
    p.add_argument(
        "out",
        help="the .onnx file to write (OUT.json and the garment's OUT.obj are written beside it)",
    )
    p.add_argument(
        "--checkpoint",
        default=None,
        help="a motion-stage, detail or packaged checkpoint (default: the pretrained set)",
    )
    p.add_argument(
        "--tier",
        default="full",
        choices=("full", "engine"),
        help="full: the learned runtime of the paper's model (default); engine: the engine "
        "tier, a linear garment basis and capsules for the engine's collider, tens of "
        "microseconds a character (its engine.pt: beside --checkpoint's motion.pt, or "
        "--checkpoint itself)",
    )
    add_generative_arg(p)
    p.add_argument("--detail", default=None, help="a detail stage's checkpoint to include")
    p.add_argument("--no-detail", action="store_true", help="leave the detail stage out")
    p.add_argument("--opset", type=int, default=17, help="ONNX opset (16-20)")
    p.add_argument(
        "--no-check",
        action="store_true",
        help="skip running a frame through onnxruntime against PyTorch",
    )
    p.set_defaults(func=run_export_model)


def run_export(args: argparse.Namespace) -> int:
    from loosefit.api.export import export_sequence

    files = export_sequence(
        args.sequence, args.out, body=not args.no_body, config=export_config(args)
    )
    log_exported(files)
    return 0


def run_export_model(args: argparse.Namespace) -> int:
    from loosefit.api import pretrained_checkpoint
    from loosefit.api.export import OnnxExportConfig, export_onnx
    from loosefit.cli.common import open_model

    checkpoint = Path(args.checkpoint) if args.checkpoint else pretrained_checkpoint()
    if args.tier == "engine":
        return _export_engine(checkpoint, args)
    model = open_model(checkpoint, args.generative, args.detail)
    config = OnnxExportConfig(opset=args.opset, detail=not args.no_detail, check=not args.no_check)
    log(f"exporting {checkpoint} to ONNX (opset {config.opset})")
    done = export_onnx(model, args.out, config=config)
    log(
        f"wrote {done.onnx} ({done.onnx.stat().st_size / 1e6:.1f} MB), {done.json} and "
        f"{done.obj} (the garment's mesh)"
    )
    if done.residual is not None:
        log(f"and {done.residual}: the set's residual process, for realisations of the cloth")
    check = done.check  # what the export recorded
    if check is None:
        log("not checked against PyTorch (--no-check)")
    else:
        log(
            f"checked: onnxruntime {check['onnxruntime']} equals PyTorch within "
            f"{check['max_difference_m']:.2g} m over {check['frames']} frames (the rest pose, "
            f"then a bent one; {done.tolerance:g} m allowed)"
        )
    return 0


def _export_engine(checkpoint: Path, args: argparse.Namespace) -> int:
    from loosefit.api.export import EngineExportConfig, engine_checkpoint, export_engine

    path = engine_checkpoint(checkpoint)
    config = EngineExportConfig(opset=args.opset, check_frames=0 if args.no_check else 300)
    log(f"exporting the engine tier {path} to ONNX (opset {config.opset})")
    done = export_engine(path, args.out, config=config)
    log(
        f"wrote {done.onnx} ({done.onnx.stat().st_size / 1e6:.1f} MB), {done.json} (with "
        f"{len(done.metadata['capsules'])} capsules) and {done.obj} (the garment's mesh)"
    )
    check = done.check
    if check is None:
        log("not checked against PyTorch (--no-check)")
    else:
        log(
            f"checked: onnxruntime {check['onnxruntime']}'s reference loop equals PyTorch "
            f"within {check['max_difference_m']:.2g} m over {check['frames']} frames of "
            f"{check['motion']} ({done.tolerance:g} m allowed)"
        )
    return 0
