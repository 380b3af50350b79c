"""Motion capture files of every kind, read into one clip type by their suffix.

BVH (:mod:`loosefit.motion.bvh`), glTF/GLB (:mod:`loosefit.motion.gltf`) and SMPL-family
``.npz`` pose files (:mod:`loosefit.motion.smpl`) all become a
:class:`~loosefit.motion.skeleton_clip.BvhClip`, which
:func:`~loosefit.motion.retarget.retarget_bvh` maps onto the avatar. A ``.npz`` saved by
loosefit (:meth:`Motion.save`) is a motion already, not a clip: :func:`is_capture_file`
tells the two apart by their fields.
:func:`motion_files` lists a folder's motions of every kind (a data set's motion folder).
"""

from __future__ import annotations

from pathlib import Path

from loosefit.errors import LoosefitInputError
from loosefit.motion.bvh import read_bvh
from loosefit.motion.gltf import read_gltf
from loosefit.motion.retarget import RetargetConfig
from loosefit.motion.skeleton_clip import BvhClip
from loosefit.motion.smpl import is_smpl_npz, npz_fields, read_smpl_npz


def _bvh(path: Path, config: RetargetConfig) -> BvhClip:
    return read_bvh(path, units=config.units, scale=config.scale)


def _gltf(path: Path, config: RetargetConfig) -> BvhClip:
    return read_gltf(path, config.animation, config.skin, units=config.units, scale=config.scale)


def _smpl(path: Path, config: RetargetConfig) -> BvhClip:
    return read_smpl_npz(path, config.smpl_up)


# suffix -> (what the file is, its reader)
CLIP_READERS = {
    ".bvh": ("a BVH file", _bvh),
    ".gltf": ("a glTF file", _gltf),
    ".glb": ("a GLB file", _gltf),
    ".npz": ("an SMPL pose .npz", _smpl),
}


def is_capture_file(path: str | Path) -> bool:
    """Whether ``path`` is read as a clip to retarget: a BVH or glTF file, or an ``.npz``
    with SMPL ``poses`` (a loosefit motion ``.npz`` has ``rotations``)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        return path.is_file() and is_smpl_npz(npz_fields(path))
    return suffix in CLIP_READERS


def read_clip(path: str | Path, config: RetargetConfig | None = None) -> BvhClip:
    """Read a motion capture file by its suffix (see :data:`CLIP_READERS`).

    Args:
        path: a ``.bvh``, ``.gltf``, ``.glb`` or SMPL ``.npz`` file.
        config: how to read it: ``units``/``scale`` (BVH, glTF), ``animation``/``skin``
            (glTF), ``smpl_up`` (SMPL).

    Returns:
        The clip, in the file's axes (SMPL's turned to Y up).

    Raises:
        LoosefitInputError: a missing file, an unknown suffix, or the reader's errors.
    """
    path = Path(path)
    config = config or RetargetConfig()
    suffix = path.suffix.lower()
    if suffix not in CLIP_READERS:
        raise LoosefitInputError(path, "suffix", f"one of {list(CLIP_READERS)}", repr(suffix))
    what, reader = CLIP_READERS[suffix]
    if not path.is_file():
        raise LoosefitInputError(
            path, "<file>", f"an existing {what.split(' ', 1)[1]}", "no such file"
        )
    return reader(path, config)


MOTION_SUFFIXES = (".bvh", ".gltf", ".glb", ".npz")  # what a folder of motions holds


def motion_files(folder: str | Path) -> list[Path]:
    """The motion files of a folder, sorted by name: BVH, glTF/GLB, SMPL-family ``.npz`` and
    loosefit motion ``.npz`` files (:meth:`Motion.save`), mixed; other files are left alone.

    Each becomes a clip named after its file's stem, so two files with one stem are refused.

    Raises:
        LoosefitInputError: naming the folder: missing, or with no motion file; or naming
            the files: two with one stem, an ``.npz`` that is no motion (neither SMPL
            ``poses`` nor loosefit ``rotations``).
    """
    folder = Path(folder)
    want = f"a folder with motion files ({', '.join(MOTION_SUFFIXES)})"
    if not folder.is_dir():
        raise LoosefitInputError(folder, "<folder>", want, "no such folder")
    files = sorted(
        f for f in folder.iterdir() if f.is_file() and f.suffix.lower() in MOTION_SUFFIXES
    )
    if not files:
        raise LoosefitInputError(folder, "<folder>", want, "no motion file")
    seen: dict[str, Path] = {}
    for f in files:
        if f.stem in seen:
            raise LoosefitInputError(
                folder,
                f.stem,
                "one file per clip name (a clip is named after its file)",
                f"{seen[f.stem].name} and {f.name}",
                hint="rename or move one of them",
            )
        seen[f.stem] = f
        if f.suffix.lower() == ".npz":
            fields = npz_fields(f)
            if not (is_smpl_npz(fields) or "rotations" in fields):
                raise LoosefitInputError(
                    f,
                    "poses",
                    "an SMPL pose file (poses, trans, a frame rate) or a loosefit "
                    "motion (rotations, ...)",
                    f"fields {sorted(fields)}",
                    hint="move files that are no motions out of the folder",
                )
    return files
