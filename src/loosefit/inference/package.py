"""A trained model as one folder to share: ``generative.pt``, ``motion.pt`` and, if trained,
``detail.pt``; weights in half precision, each stage pointing at the one before by a
relative path (no path of the machine it was trained on), each holding its
``model_config`` and no training configuration or optimiser state
(:mod:`loosefit.inference.checkpoints`)."""

from __future__ import annotations

import json
from pathlib import Path

from loosefit.inference.animator import attach_detail, load_animation_model
from loosefit.inference.checkpoints import (
    DETAIL_FORMAT,
    GENERATIVE_FORMAT,
    MOTION_FORMAT,
    half_weights,
    model_config,
    read_checkpoint_file,
    recorded_checkpoint,
    save_atomic,
)

# what a packaged stage keeps of a run's checkpoint (besides format, model_config, model)
_KEEP = {
    GENERATIVE_FORMAT: ("garment", "epoch", "physics_terms"),
    MOTION_FORMAT: (
        "generative",
        "garment",
        "num_features",
        "joint_names",
        "rest_state",
        "floor_height",
        "fps",
        "body",
        "cloth",
        "epoch",
        "physics_terms",
        "trained_on",
    ),
    DETAIL_FORMAT: ("fingerprints", "motion_checkpoint", "epoch"),
}


def packed(data: dict) -> dict:
    """A run's checkpoint dict as a packaged set holds it: its format, model
    configuration, half-precision weights and what ties it to the other stages."""
    fmt = data["format"]
    out = {"format": fmt, "model_config": model_config(data)}
    out.update({k: data[k] for k in _KEEP[fmt] if k in data})
    out["model"] = half_weights(data["model"])
    return out


def package_model(
    path: str | Path, out: str | Path, generative: str | Path | None = None
) -> tuple[Path, Path]:
    """The generative and motion stages of a trained model in one folder.

    Writes ``out/generative.pt`` and ``out/motion.pt`` (pointing at ``generative.pt``
    beside it). The fingerprint that ties them is of half-precision weights, so the
    pair loads as the original did.

    Args:
        path: a motion-stage checkpoint (``model.pt`` or ``checkpoint.pt`` of a run).
        out: the folder to write.
        generative: its generative checkpoint, if not the one it records.

    Returns:
        The paths of the generative and the motion files.
    """
    path, out = Path(path), Path(out)
    load_animation_model(path, generative)  # checks the pair belongs together
    data = read_checkpoint_file(path, MOTION_FORMAT)
    gpath = recorded_checkpoint(
        path,
        data["generative"],
        generative,
        "generative",
        "the generative checkpoint it was trained on",
        "pass --generative FILE",
    )
    out.mkdir(parents=True, exist_ok=True)
    gout, mout = out / "generative.pt", out / "motion.pt"
    save_atomic(packed(read_checkpoint_file(gpath, GENERATIVE_FORMAT)), gout)
    motion = packed(data)
    motion["generative"] = {**data["generative"], "relative": gout.name, "absolute": None}
    record = training_record(data.get("dataset"), data.get("config", {}))
    if record is not None:
        motion["trained_on"] = record
    save_atomic(motion, mout)
    return gout, mout


def package_detail(path: str | Path, out: str | Path) -> Path:
    """A detail stage into a packaged set (``out/detail.pt``, beside the ``motion.pt`` that
    :func:`package_model` wrote), pointing at ``motion.pt`` by a relative path."""
    path, out = Path(path), Path(out)
    data = read_checkpoint_file(path, DETAIL_FORMAT)
    attach_detail(load_animation_model(out / "motion.pt"), path)  # checks that it belongs
    detail = packed(data)
    detail["motion_checkpoint"] = {"relative": "motion.pt", "absolute": None}
    dout = out / "detail.pt"
    save_atomic(detail, dout)
    return dout


def training_record(dataset: str | None, config: dict) -> dict | None:
    """What a motion run was trained on, as a packaged set records it: the data set's name and
    preset, its training clips and their frames, and whether mirrored copies were added (no
    path of the machine it was trained on). None when the data set is not there to read.
    """
    if not dataset or not (Path(dataset) / "manifest.json").is_file():
        return None
    manifest = json.loads((Path(dataset) / "manifest.json").read_text())
    clips = list(manifest.get("split", {}).get("train", []))
    entries = manifest.get("sequences", {})
    return {
        "dataset": Path(dataset).name,
        "preset": manifest.get("preset"),
        "clips": clips,
        "frames": sum(_frames(Path(dataset), c, entries.get(c, {})) for c in clips),
        "mirrored": bool(config.get("mirror", False)),
        # the set it was fine-tuned from (its folder's name), or None: trained from scratch
        "started_from": Path(config["init"]).parent.name if config.get("init") else None,
    }


def _frames(dataset: Path, clip: str, entry: dict) -> int:
    """A clip's frames: its manifest entry's, else its sequence file's motion."""
    if isinstance(entry.get("frames"), int):
        return entry["frames"]
    import numpy as np

    with np.load(dataset / "sequences" / f"{clip}.npz", allow_pickle=False) as data:
        return int(data["rotations"].shape[0])


def describe_training(record: dict | None) -> str:
    """A packaged set's training record in words: "the `dance` data set (16 clips, 5,656
    frames, and their mirror images), fine-tuned from the `salsa` set"; for a set packaged
    before the record existed, that it does not say."""
    if not record:
        return "a data set it does not record"
    mirrored = ", and their mirror images" if record.get("mirrored") else ""
    start = record.get("started_from")
    tuned = f", fine-tuned from the `{start}` set" if start else ""
    return (
        f"the `{record['dataset']}` data set ({len(record['clips'])} clips, "
        f"{record['frames']:,} frames{mirrored}){tuned}"
    )
