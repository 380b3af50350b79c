"""Motion capture files of every kind, read into one clip type by their suffix.

BVH (:mod:`loosefit.body.bvh`), glTF/GLB (:mod:`loosefit.body.gltf`) and SMPL-family
``.npz`` pose files (:mod:`loosefit.body.smpl`) all become a
:class:`~loosefit.body.bvh.BvhClip`, which :func:`~loosefit.body.retarget.retarget_bvh`
maps onto the avatar. A ``.npz`` saved by loosefit (:meth:`Motion.save`) is a motion
already, not a clip: :func:`is_capture_file` tells the two apart by their fields.
"""

from __future__ import annotations

from pathlib import Path

from loosefit.body.bvh import BvhClip, read_bvh
from loosefit.body.gltf import read_gltf
from loosefit.body.retarget import RetargetConfig
from loosefit.body.smpl import is_smpl_npz, npz_fields, read_smpl_npz
from loosefit.errors import LoosefitInputError


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
        raise LoosefitInputError(path, "<file>", f"an existing {what.split(' ', 1)[1]}",
                                 "no such file")  # fmt: skip
    return reader(path, config)
