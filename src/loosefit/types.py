"""Core data types shared by every stage.

Conventions, stated once and kept everywhere in loosefit:

* Units are **metres**, seconds and radians.
* The world is **right-handed, Z up**; the avatar stands on the plane z = 0 and,
  at its reference pose, faces **-Y** (its left hand points to +X). These are the
  conventions of the ``anny`` body model. Motion capture in other conventions
  (BVH is usually Y up, facing +Z) is converted when it is read.
* Sequences are arrays with time first: ``(T, ...)``. Shapes use one vocabulary:
  T frames, J joints, V garment vertices, Vb body vertices, F faces, U UV
  coordinates.
* Data containers hold ``numpy`` arrays (float32 for geometry, int64 for
  indices); modules convert to ``torch`` where they compute.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from loosefit.errors import LoosefitInputError


def _check_array(
    source: str,
    name: str,
    array: np.ndarray,
    shape: tuple[int | None, ...],
    kind: str = "f",
) -> None:
    """Raise a :class:`LoosefitInputError` unless ``array`` has ``shape`` and no NaN.

    A ``None`` in ``shape`` accepts any size on that axis.
    """
    if not isinstance(array, np.ndarray):
        raise LoosefitInputError(source, name, "a numpy array", type(array).__name__)
    want = "(" + ", ".join("*" if s is None else str(s) for s in shape) + ")"
    if array.ndim != len(shape) or any(
        s is not None and a != s for a, s in zip(array.shape, shape, strict=True)
    ):
        raise LoosefitInputError(source, name, f"shape {want}", f"shape {tuple(array.shape)}")
    if kind == "f":
        if not np.issubdtype(array.dtype, np.floating):
            raise LoosefitInputError(source, name, "a float array", f"dtype {array.dtype}")
        bad = ~np.isfinite(array)
        if bad.any():
            first = tuple(int(i) for i in np.argwhere(bad)[0])
            raise LoosefitInputError(
                source, name, "finite values", f"{int(bad.sum())} NaN/inf values, first at {first}"
            )
    elif kind == "i" and not np.issubdtype(array.dtype, np.integer):
        raise LoosefitInputError(source, name, "an integer array", f"dtype {array.dtype}")


def _plain(x):
    """JSON fallback for numpy values in ``meta`` dicts."""
    return x.tolist() if hasattr(x, "tolist") else str(x)


def npz_names(data, path, field: str) -> tuple[str, ...]:
    """A field of names (a 1-D string array) of an ``.npz`` as a tuple of str."""
    a = np.asarray(data[field])
    if a.ndim != 1 or a.dtype.kind not in "US":
        raise LoosefitInputError(
            path, field, "a 1-D array of names", f"shape {a.shape}, dtype {a.dtype}"
        )
    return tuple(str(n) for n in a)


def npz_number(data, path, field: str) -> float:
    """A scalar number field of an ``.npz`` as a float (finite)."""
    a = np.asarray(data[field])
    if a.size != 1 or a.dtype.kind not in "fiu" or not np.isfinite(a).all():
        raise LoosefitInputError(
            path,
            field,
            "one finite number",
            f"shape {a.shape}, dtype {a.dtype}"
            if a.size != 1 or a.dtype.kind not in "fiu"
            else repr(a.item()),
        )
    return float(a.reshape(()))


def npz_text(data, path, field: str, default: str | None = None) -> str:
    """A text field (a 0-d string array) of an ``.npz``; ``default`` when absent."""
    if field not in data and default is not None:
        return default
    a = np.asarray(data[field])
    if a.ndim != 0 or a.dtype.kind not in "US":
        raise LoosefitInputError(path, field, "a text", f"shape {a.shape}, dtype {a.dtype}")
    return str(a)


def _numeric(data, path, field: str) -> np.ndarray:
    """A numeric array field of an ``.npz`` (numbers, not text or complex)."""
    a = np.asarray(data[field])
    if a.dtype.kind not in "fiub":
        raise LoosefitInputError(path, field, "an array of numbers", f"dtype {a.dtype}")
    return a


class NpzData(dict):
    """The arrays of an ``.npz`` file, all read (name -> array), with ``files`` as numpy's."""

    @property
    def files(self) -> list[str]:
        return list(self)


def load_npz(path: str | Path, what: str, required: tuple[str, ...]) -> NpzData:
    """Read every array of an ``.npz`` file (no pickle: an object array is refused) and check
    that it has the ``required`` fields.

    Args:
        path: the file.
        what: what the file should be, for messages (e.g. "a .npz motion file").
        required: field names that must be present.

    Raises:
        LoosefitInputError: naming the file (and the field): unreadable, not an ``.npz``,
            truncated, a pickled object in a field, or a field missing.
    """
    import zipfile

    path = Path(path)
    data = NpzData()
    field = "<file>"
    try:
        z = np.load(path, allow_pickle=False)
        if not hasattr(z, "files"):  # a .npy: one array, read whole
            raise LoosefitInputError(path, "<file>", what, "a single array, not an .npz")
        with z:
            for field in z.files:
                data[field] = z[field]
    except LoosefitInputError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as exc:
        found = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        if "allow_pickle" in found:
            found = "a pickled object (refused: loading it could run code)"
        raise LoosefitInputError(path, field, what, found) from exc
    missing = sorted(set(required) - set(data))
    if missing:
        raise LoosefitInputError(path, ", ".join(missing), "present", "missing")
    return data


@dataclass
class Motion:
    """A body motion on the avatar's skeleton.

    Rotations are **local** and relative to the avatar's reference pose, in the
    SMPL convention: with ``G_j`` the world rotation that carries joint ``j``
    from its reference orientation to its posed one, ``G_j = G_parent(j) @
    rotations[:, j]`` and ``G_root = rotations[:, 0]``. Identity everywhere is
    the avatar's reference pose (anny's A-pose), facing -Y.

    Attributes:
        joint_names: J names, in the order of the avatar's skeleton.
        rotations: (T, J, 3, 3) float32 local rotation matrices.
        root_translation: (T, 3) float32 world position of the root joint, metres.
        fps: frames per second.
        name: a label for messages and file names.
    """

    joint_names: tuple[str, ...]
    rotations: np.ndarray
    root_translation: np.ndarray
    fps: float
    name: str = "motion"
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.joint_names = tuple(self.joint_names)
        self.rotations = np.asarray(self.rotations, dtype=np.float32)
        self.root_translation = np.asarray(self.root_translation, dtype=np.float32)
        self.validate()

    @property
    def num_frames(self) -> int:
        return int(self.rotations.shape[0])

    @property
    def num_joints(self) -> int:
        return len(self.joint_names)

    @property
    def duration(self) -> float:
        """Seconds from the first to the last frame."""
        return (self.num_frames - 1) / self.fps

    def validate(self) -> None:
        """Check shapes, finiteness, orthonormality and the frame rate."""
        src = f"motion '{self.name}'"
        J = len(self.joint_names)
        if J == 0:
            raise LoosefitInputError(src, "joint_names", "at least one joint", "none")
        if len(set(self.joint_names)) != J:
            dup = sorted({n for n in self.joint_names if self.joint_names.count(n) > 1})
            raise LoosefitInputError(src, "joint_names", "unique names", f"duplicates {dup}")
        _check_array(src, "rotations", self.rotations, (None, J, 3, 3))
        T = self.rotations.shape[0]
        if T < 1:
            raise LoosefitInputError(src, "rotations", "at least one frame", "0 frames")
        _check_array(src, "root_translation", self.root_translation, (T, 3))
        err = np.abs(
            self.rotations @ np.swapaxes(self.rotations, -1, -2) - np.eye(3, dtype=np.float32)
        ).max()
        if err > 1e-3:
            raise LoosefitInputError(
                src, "rotations", "orthonormal 3x3 matrices", f"max |R R^T - I| = {err:.3g}"
            )
        det = np.linalg.det(self.rotations.astype(np.float64))
        if (det < 0).any():
            raise LoosefitInputError(
                src, "rotations", "proper rotations (det +1)", f"{int((det < 0).sum())} reflections"
            )
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise LoosefitInputError(src, "fps", "a positive frame rate", repr(self.fps))

    def slice(self, start: int, stop: int | None = None) -> Motion:
        """Frames ``start:stop`` as a new motion."""
        return Motion(
            self.joint_names,
            self.rotations[start:stop],
            self.root_translation[start:stop],
            self.fps,
            self.name,
            dict(self.meta),
        )

    def save(self, path: str | Path) -> None:
        """Write to ``.npz`` (readable with plain numpy)."""
        np.savez(
            path,
            joint_names=np.array(self.joint_names),
            rotations=self.rotations,
            root_translation=self.root_translation,
            fps=np.float64(self.fps),
            name=np.array(self.name),
        )

    @classmethod
    def load(cls, path: str | Path) -> Motion:
        """Read a motion written by :meth:`save`, validating every field."""
        path = Path(path)
        data = load_npz(
            path, "a .npz motion file", ("joint_names", "rotations", "root_translation", "fps")
        )
        return cls.from_npz(data, path)

    @classmethod
    def from_npz(cls, data, path: Path) -> Motion:
        """A motion from an opened ``.npz`` holding its fields; errors name ``path``."""
        try:
            return cls(
                npz_names(data, path, "joint_names"),
                _numeric(data, path, "rotations"),
                _numeric(data, path, "root_translation"),
                npz_number(data, path, "fps"),
                npz_text(data, path, "name", Path(path).stem),
            )
        except LoosefitInputError as exc:
            raise LoosefitInputError(path, exc.field, exc.expected, exc.found) from exc


@dataclass
class GarmentTemplate:
    """A garment mesh at rest, with a UV layout and its waistband.

    UVs are stored per face corner, as in OBJ, so a vertex on a UV seam may
    have several UV coordinates.

    Attributes:
        vertices: (V, 3) float32 rest positions, metres, in the avatar's frame.
        faces: (F, 3) int64 triangle vertex indices, counter-clockwise seen from
            outside (normals point away from the body).
        uvs: (U, 2) float32 UV coordinates in the unit square.
        face_uvs: (F, 3) int64 indices into ``uvs`` for each face corner.
        waist: (W,) int64 indices of the waistband vertices (attached to the body).
        name: a label.
        rest_vertices: (V, 3) float32 the cloth's rest shape (its unstretched edge lengths
            and triangles) when it is not ``vertices``, the positions the garment starts
            from: a garment fitted to the avatar (``garment --fit``) starts draped on it
            and keeps the file's rest lengths. Any rigid placement (only lengths and
            angles are read from it). None: ``vertices`` are both.
    """

    vertices: np.ndarray
    faces: np.ndarray
    uvs: np.ndarray
    face_uvs: np.ndarray
    waist: np.ndarray
    name: str = "garment"
    meta: dict = field(default_factory=dict)
    rest_vertices: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.vertices = np.asarray(self.vertices, dtype=np.float32)
        self.faces = np.asarray(self.faces, dtype=np.int64)
        self.uvs = np.asarray(self.uvs, dtype=np.float32)
        self.face_uvs = np.asarray(self.face_uvs, dtype=np.int64)
        self.waist = np.asarray(self.waist, dtype=np.int64)
        if self.rest_vertices is not None:
            self.rest_vertices = np.asarray(self.rest_vertices, dtype=np.float32)
        self.validate()

    @property
    def num_vertices(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def rest(self) -> np.ndarray:
        """(V, 3) the rest shape: ``rest_vertices`` if given, else ``vertices``."""
        return self.vertices if self.rest_vertices is None else self.rest_vertices

    def validate(self) -> None:
        """Check shapes, index ranges and finiteness."""
        src = f"garment '{self.name}'"
        _check_array(src, "vertices", self.vertices, (None, 3))
        _check_array(src, "faces", self.faces, (None, 3), kind="i")
        _check_array(src, "uvs", self.uvs, (None, 2))
        _check_array(src, "face_uvs", self.face_uvs, (self.faces.shape[0], 3), kind="i")
        _check_array(src, "waist", self.waist, (None,), kind="i")
        V, U = self.vertices.shape[0], self.uvs.shape[0]
        if self.rest_vertices is not None:
            _check_array(src, "rest_vertices", self.rest_vertices, (V, 3))
        if self.faces.shape[0] == 0:
            raise LoosefitInputError(src, "faces", "at least one face", "0 faces")
        for name, idx, n in (("faces", self.faces, V), ("face_uvs", self.face_uvs, U)):
            if idx.min() < 0 or idx.max() >= n:
                raise LoosefitInputError(
                    src, name, f"indices in [0, {n})", f"range [{idx.min()}, {idx.max()}]"
                )
        if len(self.waist) and (self.waist.min() < 0 or self.waist.max() >= V):
            raise LoosefitInputError(
                src,
                "waist",
                f"indices in [0, {V})",
                f"range [{self.waist.min()}, {self.waist.max()}]",
            )
        if (self.uvs < -1e-6).any() or (self.uvs > 1 + 1e-6).any():
            raise LoosefitInputError(
                src,
                "uvs",
                "coordinates in the unit square",
                f"range [{self.uvs.min():.3g}, {self.uvs.max():.3g}]",
            )

    def save(self, path: str | Path) -> None:
        """Write to ``.npz`` (readable with plain numpy)."""
        np.savez(
            path,
            vertices=self.vertices,
            faces=self.faces,
            uvs=self.uvs,
            face_uvs=self.face_uvs,
            waist=self.waist,
            name=np.array(self.name),
            meta=np.array(json.dumps(self.meta, default=_plain)),
            **({} if self.rest_vertices is None else {"rest_vertices": self.rest_vertices}),
        )

    @classmethod
    def load(cls, path: str | Path) -> GarmentTemplate:
        """Read a template written by :meth:`save`, validating every field (one written
        before ``rest_vertices``, or without them: its vertices are its rest shape)."""
        path = Path(path)
        need = ("vertices", "faces", "uvs", "face_uvs", "waist")
        data = load_npz(path, "a .npz garment template", need)
        try:
            meta = json.loads(npz_text(data, path, "meta", "{}"))
        except json.JSONDecodeError as exc:
            raise LoosefitInputError(path, "meta", "JSON", str(exc)) from exc
        try:
            return cls(
                **{k: _numeric(data, path, k) for k in need},
                name=npz_text(data, path, "name", path.stem),
                meta=meta if isinstance(meta, dict) else {},
                rest_vertices=_numeric(data, path, "rest_vertices")
                if "rest_vertices" in data
                else None,
            )
        except LoosefitInputError as exc:
            raise LoosefitInputError(path, exc.field, exc.expected, exc.found) from exc
