"""The on-disk dataset: simulated garment sequences on a moving avatar.

A dataset is a folder, readable with plain numpy and json::

    manifest.json           what made it: configs, package versions, seeds, the
                            split, per-sequence quality, and "complete"
    template.npz            the garment at rest: vertices (V, 3) float32, faces
                            (F, 3) int64, uvs (U, 2) float32, face_uvs (F, 3)
                            int64, waist (W,) int64, name
    rest_drape.npy          the garment settled on the rest pose (V, 3) float32, in the
                            rest pose's root frame: where every clip and every learned
                            rollout starts (absent from data sets simulated before it
                            was written: :mod:`loosefit.sim.rest_drape` settles it again)
    sequences/NAME.npz      one clip: an animated garment in the one sequence format
                            (:mod:`loosefit.sequence`), the motion and the simulated
                            garment (T, V, 3) float32, with the template and the body

The body is described in the manifest (``body``: model, rig, shape,
floor_height) and reproduced by posing the avatar with each clip's motion.
A clip written before the sequence format (no ``format`` field: the motion's
fields and ``garment_vertices`` alone) is still read, with the data set's
template and body.
Conventions as everywhere in loosefit: metres, Z up, the avatar faces -Y.
A sequence file is written to a temporary name and renamed when complete
(:func:`~loosefit.atomic.atomic_path`), so a half-written file is never taken
for a whole one.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from loosefit.atomic import atomic_path
from loosefit.errors import LoosefitInputError
from loosefit.garment.fingerprint import (
    avatar_fingerprint,
    avatar_key,
    cloth_fingerprint,
    garment_fingerprint,
    same_garment,
)
from loosefit.sequence import GarmentSequence
from loosefit.types import GarmentTemplate, Motion, _check_array, load_npz

FORMAT = "loosefit.dataset/1"
LEGACY_FIELDS = ("joint_names", "rotations", "root_translation", "fps", "garment_vertices")


def write_json_atomic(path: Path, data: dict) -> None:
    """Write JSON to ``path`` through a temporary file and a rename."""
    with atomic_path(Path(path)) as tmp:
        tmp.write_text(json.dumps(data, indent=2, sort_keys=False, default=_jsonable))


def _jsonable(x):
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, Path):
        return str(x)
    raise TypeError(f"not JSON serialisable: {type(x).__name__}")


def write_sequence(path: Path, seq: GarmentSequence) -> Path:
    """Write one clip atomically (:meth:`~loosefit.sequence.GarmentSequence.save`)."""
    return seq.save(path)


def read_sequence(
    path: Path, template: GarmentTemplate | None = None, avatar: dict | None = None
) -> GarmentSequence:
    """Read and validate one clip, named after its file; with ``template``, check that it
    is of that garment.

    A clip in the sequence format is read whole; an earlier data set's clip (no
    ``format`` field) takes ``template`` and ``avatar`` (the data set's), which it needs.

    Raises:
        LoosefitInputError: naming the file and field for a missing field, a
            wrong shape or dtype, NaN, or another garment than ``template``.
    """
    path = Path(path)
    d = load_npz(path, "a sequence .npz", ())
    if "format" not in d.files and "garment_vertices" in d.files and template is not None:
        seq = _read_legacy(path, d, template, avatar or {})
    else:
        seq = GarmentSequence.load(path)
    if template is not None and not same_garment(seq.garment, template):
        raise LoosefitInputError(
            path,
            "vertices, faces",
            f"the data set's garment ({template.num_vertices} "
            f"vertices, fingerprint {_garment_print(template)})",
            f"another garment ({seq.garment.num_vertices} vertices, fingerprint "
            f"{_garment_print(seq.garment)})",
            hint="a data set holds one garment: simulate each garment into its own",
        )
    if avatar is not None and avatar_key(seq.avatar) != avatar_key(avatar):
        raise LoosefitInputError(
            path,
            "avatar",
            f"the data set's avatar {avatar} (fingerprint {avatar_fingerprint(avatar)})",
            f"another avatar {seq.avatar} (fingerprint {avatar_fingerprint(seq.avatar)})",
            hint="a data set holds one avatar: simulate each body into its own",
        )
    seq.motion.name = path.stem  # its clip's name (validated already)
    return seq


def _garment_print(garment: GarmentTemplate) -> str:
    return garment_fingerprint(np.asarray(garment.vertices), np.asarray(garment.faces))


def _read_legacy(path: Path, d, template: GarmentTemplate, avatar: dict) -> GarmentSequence:
    missing = sorted(set(LEGACY_FIELDS) - set(d.files))
    if missing:
        raise LoosefitInputError(path, ", ".join(missing), "present", "missing")
    gv = d["garment_vertices"]
    T = gv.shape[0] if gv.ndim == 3 else -1
    _check_array(str(path), "garment_vertices", gv, (None, template.num_vertices, 3))
    for key in ("rotations", "root_translation", "garment_vertices"):
        if d[key].dtype != np.float32:
            raise LoosefitInputError(path, key, "dtype float32", f"dtype {d[key].dtype}")
    names = tuple(str(n) for n in d["joint_names"])
    _check_array(str(path), "rotations", d["rotations"], (T, len(names), 3, 3))
    return GarmentSequence(Motion.from_npz(d, path), template, gv, avatar, "simulation")


def _check_manifest(path: Path, m: dict) -> None:
    """The manifest's fields the readers rely on, with the types they need."""
    split = m.get("split")
    if not isinstance(split, dict):
        raise LoosefitInputError(path, "split", "{train: [...], test: [...]}", repr(split))
    for key in ("train", "test"):
        names = split.get(key)
        if not isinstance(names, list) or not all(isinstance(n, str) and n for n in names):
            raise LoosefitInputError(path, f"split.{key}", "a list of clip names", repr(names))
        bad = [n for n in names if "/" in n or "\\" in n or n.startswith(".")]
        if bad:
            raise LoosefitInputError(path, f"split.{key}", "clip names (no paths)", repr(bad[0]))
    body = m.get("body")
    if not isinstance(body, dict):
        raise LoosefitInputError(path, "body", "the avatar's description", repr(body))
    shape = body.get("shape", {})
    if not isinstance(shape, dict) or not all(
        isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
        for v in shape.values()
    ):
        raise LoosefitInputError(path, "body.shape", "anny phenotype numbers", repr(shape))
    floor = body.get("floor_height", 0.0)
    if not isinstance(floor, int | float) or isinstance(floor, bool) or not math.isfinite(floor):
        raise LoosefitInputError(path, "body.floor_height", "a number (m)", repr(floor))
    if not isinstance(m.get("complete", False), bool):
        raise LoosefitInputError(path, "complete", "true or false", repr(m.get("complete")))


class DatasetReader:
    """A dataset folder: its manifest, template, and validated sequences.

    Args:
        root: the dataset folder.
        allow_incomplete: accept a dataset whose generation has not finished.
    """

    def __init__(self, root: str | Path, allow_incomplete: bool = False) -> None:
        self.root = Path(root)
        mpath = self.root / "manifest.json"
        if not mpath.is_file():
            raise LoosefitInputError(
                self.root, "manifest.json", "a loosefit dataset", "no manifest"
            )
        try:
            self.manifest = json.loads(mpath.read_text())
        except json.JSONDecodeError as exc:
            raise LoosefitInputError(mpath, "<file>", "valid JSON", str(exc)) from exc
        if not isinstance(self.manifest, dict):
            raise LoosefitInputError(mpath, "<file>", "a JSON object", type(self.manifest).__name__)
        fmt = self.manifest.get("format")
        if fmt != FORMAT:
            raise LoosefitInputError(mpath, "format", repr(FORMAT), repr(fmt))
        _check_manifest(mpath, self.manifest)
        if not self.manifest.get("complete") and not allow_incomplete:
            raise LoosefitInputError(
                mpath,
                "complete",
                "a finished dataset",
                "an unfinished one",
                hint="rerun the same `loosefit simulate` command to finish it",
            )
        self.template = GarmentTemplate.load(self.root / "template.npz")

    @property
    def body(self) -> dict:
        """The avatar's description: model, rig, shape, floor_height."""
        return self.manifest["body"]

    @property
    def rest_drape(self) -> np.ndarray | None:
        """(V, 3) float32 the garment settled on the rest pose (``rest_drape.npy``), or None
        for a data set simulated before the simulator wrote it.

        Raises:
            LoosefitInputError: the file is unreadable, or not (V, 3) finite numbers.
        """
        path = self.root / "rest_drape.npy"
        if not path.is_file():
            return None
        try:
            drape = np.load(path, allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise LoosefitInputError(path, "<file>", "a readable .npy", str(exc)) from exc
        V = self.template.num_vertices
        if drape.shape != (V, 3) or not np.issubdtype(drape.dtype, np.floating):
            raise LoosefitInputError(
                path,
                "<array>",
                f"({V}, 3) floats (the template's vertices)",
                f"{drape.shape} {drape.dtype}",
            )
        if not np.isfinite(drape).all():
            raise LoosefitInputError(path, "<array>", "finite numbers", "NaN or infinity")
        return drape.astype(np.float32)

    def split(self, name: str) -> list[str]:
        """Sequence names of a split ("train", "test" or "all")."""
        if name == "all":
            return list(self.manifest["split"]["train"]) + list(self.manifest["split"]["test"])
        if name not in self.manifest["split"]:
            raise LoosefitInputError(
                self.root / "manifest.json", "split", "train, test or all", repr(name)
            )
        return list(self.manifest["split"][name])

    def check_uniform(self, names: list[str]) -> None:
        """Refuse clips simulated under another cloth configuration than the manifest's.

        Each clip's entry records its configuration's fingerprint (``cloth_fingerprint``,
        the device left out); an entry without one (a data set made before it was
        recorded) is taken as the manifest's configuration. The garment and the avatar are
        checked as each clip is read (:func:`read_sequence`).

        Raises:
            LoosefitInputError: naming the manifest, the clip and both fingerprints.
        """
        mpath = self.root / "manifest.json"
        cloth = self.manifest.get("config", {}).get("cloth")
        ours = cloth_fingerprint(cloth) if isinstance(cloth, dict) else None
        entries = self.manifest.get("sequences", {})
        for name in names:
            theirs = entries.get(name, {}).get("cloth_fingerprint")
            if theirs is None:
                continue
            if ours is None:  # no configuration in the manifest: the first clip's
                ours = theirs
            elif theirs != ours:
                raise LoosefitInputError(
                    mpath,
                    f"sequences.{name}.cloth_fingerprint",
                    f"the data set's cloth configuration (fingerprint {ours})",
                    f"clip {name} simulated under another one (fingerprint {theirs})",
                    hint="a data set holds one garment, avatar and cloth configuration: "
                    "simulate the other into its own",
                )

    def training_clips(self, split: str) -> list[str]:
        """The clips of a split to train on: at least one, all of the data set's cloth
        configuration (:meth:`check_uniform`)."""
        names = self.split(split)
        if not names:
            raise LoosefitInputError(self.root, f"split '{split}'", "at least one clip", "none")
        self.check_uniform(names)
        return names

    def sequence_path(self, name: str) -> Path:
        return self.root / "sequences" / f"{name}.npz"

    @property
    def avatar(self) -> dict:
        """The body as a sequence records it: ``{"rig": ..., "shape": {...}}``."""
        return {"rig": self.body.get("rig", "cmu_mb"), "shape": dict(self.body.get("shape", {}))}

    def read(self, name: str) -> GarmentSequence:
        """One validated sequence by name."""
        path = self.sequence_path(name)
        if not path.is_file():
            raise LoosefitInputError(self.root, f"sequences/{name}.npz", "present", "missing")
        return read_sequence(path, self.template, self.avatar)


def read_any_sequence(path: str | Path, reader=None) -> GarmentSequence:
    """A sequence ``.npz``: an animated garment's file, or a data set's clip (a clip of an
    earlier data set, without the sequence format, is read through its data set, or through
    ``reader``, a :class:`DatasetReader`, where given)."""
    path = Path(path)
    root = path.parent.parent
    if reader is None and path.parent.name == "sequences" and (root / "manifest.json").is_file():
        reader = DatasetReader(root, allow_incomplete=True)
    if reader is not None:
        return reader.read(path.stem)
    return GarmentSequence.load(path)
