"""The on-disk dataset: simulated garment sequences on a moving avatar.

A dataset is a folder, readable with plain numpy and json::

    manifest.json           what made it: configs, package versions, seeds, the
                            split, per-sequence quality, and "complete"
    template.npz            the garment at rest: vertices (V, 3) float32, faces
                            (F, 3) int64, uvs (U, 2) float32, face_uvs (F, 3)
                            int64, waist (W,) int64, name
    sequences/NAME.npz      one clip: joint_names (J,) str, rotations (T, J, 3, 3)
                            float32, root_translation (T, 3) float32, fps float64,
                            garment_vertices (T, V, 3) float32, name str

The body is described in the manifest (``body``: model, rig, shape,
floor_height) and reproduced by posing the avatar with each clip's motion.
Conventions as everywhere in loosefit: metres, Z up, the avatar faces -Y.
A sequence file is written to ``NAME.partial.npz`` and renamed when complete,
so a half-written file is never taken for a whole one.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from loosefit.atomic import atomic_path
from loosefit.errors import LoosefitInputError
from loosefit.types import GarmentTemplate, Motion, _check_array, load_npz

FORMAT = "loosefit.dataset/1"
SEQUENCE_FIELDS = ("joint_names", "rotations", "root_translation", "fps", "garment_vertices")


@dataclass
class Sequence:
    """One simulated clip.

    Attributes:
        name: the clip's name (its file stem).
        motion: the body's motion, T frames.
        garment_vertices: (T, V, 3) float32 simulated garment, world frame.
    """

    name: str
    motion: Motion
    garment_vertices: np.ndarray

    @property
    def num_frames(self) -> int:
        return self.motion.num_frames


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


def write_sequence(path: Path, seq: Sequence) -> Path:
    """Write one clip atomically (:func:`~loosefit.atomic.atomic_path`)."""
    path = Path(path)
    with atomic_path(path) as tmp:
        np.savez(
            tmp,
            joint_names=np.array(seq.motion.joint_names),
            rotations=seq.motion.rotations.astype(np.float32),
            root_translation=seq.motion.root_translation.astype(np.float32),
            fps=np.float64(seq.motion.fps),
            garment_vertices=np.asarray(seq.garment_vertices, np.float32),
            name=np.array(seq.name),
        )
    return path


def read_sequence(path: Path, template: GarmentTemplate | None = None) -> Sequence:
    """Read and validate one clip; with ``template``, check its vertex count too.

    Raises:
        LoosefitInputError: naming the file and field for a missing field, a
            wrong shape or dtype, NaN, or a vertex count that is not the template's.
    """
    path = Path(path)
    d = load_npz(path, "a sequence .npz", SEQUENCE_FIELDS)
    gv = d["garment_vertices"]
    T = gv.shape[0] if gv.ndim == 3 else -1
    V = template.num_vertices if template is not None else None
    _check_array(str(path), "garment_vertices", gv, (None, V, 3))
    if gv.dtype != np.float32:
        raise LoosefitInputError(path, "garment_vertices", "dtype float32", f"dtype {gv.dtype}")
    for key in ("rotations", "root_translation"):
        if d[key].dtype != np.float32:
            raise LoosefitInputError(path, key, "dtype float32", f"dtype {d[key].dtype}")
    names = tuple(str(n) for n in d["joint_names"])
    _check_array(str(path), "rotations", d["rotations"], (T, len(names), 3, 3))
    return Sequence(name=path.stem, motion=Motion.from_npz(d, path), garment_vertices=gv)


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
        fmt = self.manifest.get("format")
        if fmt != FORMAT:
            raise LoosefitInputError(mpath, "format", repr(FORMAT), repr(fmt))
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

    def split(self, name: str) -> list[str]:
        """Sequence names of a split ("train", "test" or "all")."""
        if name == "all":
            return list(self.manifest["split"]["train"]) + list(self.manifest["split"]["test"])
        if name not in self.manifest["split"]:
            raise LoosefitInputError(
                self.root / "manifest.json", "split", "train, test or all", repr(name)
            )
        return list(self.manifest["split"][name])

    def sequence_path(self, name: str) -> Path:
        return self.root / "sequences" / f"{name}.npz"

    def read(self, name: str) -> Sequence:
        """One validated sequence by name."""
        path = self.sequence_path(name)
        if not path.is_file():
            raise LoosefitInputError(self.root, f"sequences/{name}.npz", "present", "missing")
        return read_sequence(path, self.template)
