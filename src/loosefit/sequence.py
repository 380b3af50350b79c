"""An animated garment, in memory and on disk: the one format every command reads.

What ``loosefit.load().animate()``, ``loosefit.simulate()``, ``loosefit animate`` and
``loosefit simulate`` (each clip of a data set) write, and what ``render``, ``evaluate``,
``export`` and :meth:`GarmentSequence.load` read. A file is a plain ``.npz`` (numpy alone
reads it; no pickle), written atomically, with the fields::

    format            "loosefit.sequence/1"
    joint_names       (J,) str           the motion, on the avatar's skeleton
    rotations         (T, J, 3, 3) f32   local joint rotations (Motion's convention)
    root_translation  (T, 3) f32         the root joint, metres
    fps               f64
    motion_name       str
    vertices          (V, 3) f32         the garment at rest (GarmentTemplate) ...
    faces             (F, 3) i64
    uvs               (U, 2) f32
    face_uvs          (F, 3) i64
    waist             (W,) i64
    garment_name      str
    garment_meta      str (JSON)         ... and what made it (optional)
    garment_vertices  (T, V, 3) f32      the animated garment, world frame
    avatar            str (JSON)         {"rig": ..., "shape": {...}}: the body
    source            str                what moved the garment (a model, "newton-vbd")

Conventions as everywhere in loosefit: metres, Z up, the avatar faces -Y. The body is
not stored: posing the avatar (same rig and shape) with the motion reproduces it exactly
and keeps a file ~20x smaller. Every field is validated when read.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from loosefit.atomic import atomic_path
from loosefit.errors import LoosefitInputError
from loosefit.types import (
    GarmentTemplate,
    Motion,
    _check_array,
    _numeric,
    _plain,
    load_npz,
    npz_names,
    npz_number,
    npz_text,
)

FORMAT = "loosefit.sequence/1"


@dataclass
class GarmentSequence:
    """A garment animated on a moving avatar: what ``loosefit.load().animate()`` and
    ``loosefit.simulate()`` return, and what ``.npz`` sequences hold.

    Attributes:
        motion: the body's motion (T frames).
        garment: the garment template (V vertices).
        garment_vertices: (T, V, 3) float32 garment vertices, metres, world frame.
        avatar: how to rebuild the avatar: ``{"rig": ..., "shape": {...}}``.
        source: what made the garment motion (e.g. "rigid", "newton-vbd", a model).
    """

    motion: Motion
    garment: GarmentTemplate
    garment_vertices: np.ndarray
    avatar: dict
    source: str = "unknown"
    _body: np.ndarray | None = field(default=None, init=False, repr=False, compare=False)
    _body_faces: np.ndarray | None = field(default=None, init=False, repr=False, compare=False)
    _body_skin: object | None = field(default=None, init=False, repr=False, compare=False)

    @property
    def template(self) -> GarmentTemplate:
        """The garment template (``garment``)."""
        return self.garment

    @property
    def vertices(self) -> np.ndarray:
        """(T, V, 3) the garment's positions (``garment_vertices``)."""
        return self.garment_vertices

    @property
    def fps(self) -> float:
        return float(self.motion.fps)

    @property
    def num_frames(self) -> int:
        return self.motion.num_frames

    def avatar_config(self):
        """The :class:`~loosefit.body.avatar.AvatarConfig` of the body this sequence was made
        on (its ``avatar`` description: the rig, default ``cmu_mb``, and the phenotype)."""
        from loosefit.body.avatar import AvatarConfig

        return AvatarConfig(
            rig=self.avatar.get("rig", "cmu_mb"), shape=dict(self.avatar.get("shape", {}))
        )

    def _pose_body(self) -> None:
        from loosefit.body.avatar import Avatar

        avatar = Avatar(self.avatar_config())
        self.keep_body(avatar, avatar.pose_motion(self.motion))

    def keep_body(self, avatar, body) -> None:
        """Keep a body its caller has already posed (``avatar.pose_motion(self.motion)``, on
        the avatar this sequence records) as this sequence's body, so that
        :attr:`body_vertices`, :attr:`body_skin` and :meth:`export` do not build and pose
        the avatar again."""
        from loosefit.export import body_skin

        self._body = body.vertices.cpu().numpy()
        self._body_faces = avatar.faces.cpu().numpy()
        self._body_skin = body_skin(avatar, body)

    @property
    def body_vertices(self) -> np.ndarray:
        """(T, Vb, 3) the posed avatar (rebuilt from ``avatar`` and the motion, once)."""
        if self._body is None:
            self._pose_body()
        return self._body

    @property
    def body_faces(self) -> np.ndarray:
        """(Fb, 3) the avatar's triangles."""
        if self._body_faces is None:
            self._pose_body()
        return self._body_faces

    @property
    def body_skin(self):
        """The posed avatar's rig (:class:`~loosefit.export.Skin`: joints, weights, rest
        mesh and the joints' poses in every frame)."""
        if self._body_skin is None:
            self._pose_body()
        return self._body_skin

    def export(self, path: str | Path, body: bool = True, config=None) -> list[Path]:
        """Write the garment (and the body) in the format ``path``'s suffix names:
        ``.usd``/``.usdc``/``.usda`` (the body skinned), ``.abc`` (Alembic), ``.glb``
        (glTF, the body skinned), ``.pc2`` (+ OBJ), or a folder of OBJs
        (:func:`loosefit.export.export_animation`; ``config``: an
        :class:`~loosefit.export.ExportConfig`, the up axis and the body as points)."""
        from loosefit.export import check_export_path, export_animation, garment_and_body

        check_export_path(path)
        meshes = garment_and_body(
            self.garment,
            self.garment_vertices,
            self.body_vertices if body else None,
            self.body_faces if body else None,
            self.body_skin if body else None,
        )
        return export_animation(path, meshes, self.fps, config)

    def __post_init__(self) -> None:
        gv = np.asarray(self.garment_vertices)
        if np.issubdtype(gv.dtype, np.floating):
            gv = gv.astype(np.float32, copy=False)
        T, V = self.motion.num_frames, self.garment.num_vertices
        _check_array("GarmentSequence", "garment_vertices", gv, (T, V, 3))
        self.garment_vertices = gv

    @property
    def name(self) -> str:
        """The motion's name (a data set's clip name)."""
        return self.motion.name

    def save(self, path: str | Path) -> Path:
        """Write atomically to ``path`` (``.npz``; nothing is left there if it fails)."""
        path = Path(path)
        g = self.garment
        with atomic_path(path) as tmp:
            np.savez(
                tmp,
                format=np.array(FORMAT),
                joint_names=np.array(self.motion.joint_names),
                rotations=self.motion.rotations.astype(np.float32),
                root_translation=self.motion.root_translation.astype(np.float32),
                fps=np.float64(self.motion.fps),
                motion_name=np.array(self.motion.name),
                vertices=g.vertices,
                faces=g.faces,
                uvs=g.uvs,
                face_uvs=g.face_uvs,
                waist=g.waist,
                garment_name=np.array(g.name),
                garment_meta=np.array(json.dumps(g.meta or {}, default=_plain)),
                **({} if g.rest_vertices is None else {"rest_vertices": g.rest_vertices}),
                garment_vertices=self.garment_vertices,
                avatar=np.array(json.dumps(self.avatar)),
                source=np.array(self.source),
            )
        return path

    @classmethod
    def load(cls, path: str | Path) -> GarmentSequence:
        """Read and validate a file written by :meth:`save`.

        Raises:
            LoosefitInputError: naming the file and the field: not a ``.npz``, another
                format (or version), a missing field, a wrong shape or dtype, NaN.
        """
        path = Path(path)
        if not path.is_file():
            raise LoosefitInputError(path, "<file>", "an existing .npz sequence", "no such file")
        d = load_npz(path, "a .npz sequence", ())
        fmt = (
            str(d["format"]) if "format" in d.files and np.asarray(d["format"]).ndim == 0 else None
        )
        if fmt != FORMAT:
            hint = None
            if fmt is None and "garment_vertices" in d.files:
                hint = (
                    "a clip of a data set written before loosefit.sequence/1; read it "
                    "through its data set (DatasetReader, or loosefit render --dataset)"
                )
            raise LoosefitInputError(
                path, "format", repr(FORMAT), "none" if fmt is None else repr(fmt), hint=hint
            )
        missing = [k for k in _FIELDS if k not in d.files]
        if missing:
            raise LoosefitInputError(path, ", ".join(missing), "present", "missing")
        gv = d["garment_vertices"]
        floats = (
            "rotations",
            "root_translation",
            "garment_vertices",
            "vertices",
            "uvs",
            "rest_vertices",
        )
        for key in (k for k in floats if k in d.files):
            if d[key].dtype != np.float32:
                raise LoosefitInputError(path, key, "dtype float32", f"dtype {d[key].dtype}")
        try:
            avatar = json.loads(npz_text(d, path, "avatar"))
            meta = json.loads(npz_text(d, path, "garment_meta", "{}"))
        except json.JSONDecodeError as exc:
            raise LoosefitInputError(path, "avatar/garment_meta", "JSON", str(exc)) from exc
        if not isinstance(avatar, dict):
            raise LoosefitInputError(
                path, "avatar", '{"rig": ..., "shape": {...}}', type(avatar).__name__
            )
        try:
            motion = Motion(
                npz_names(d, path, "joint_names"),
                _numeric(d, path, "rotations"),
                _numeric(d, path, "root_translation"),
                npz_number(d, path, "fps"),
                npz_text(d, path, "motion_name", path.stem),
            )
            garment = GarmentTemplate(
                *(_numeric(d, path, k) for k in ("vertices", "faces", "uvs", "face_uvs", "waist")),
                name=npz_text(d, path, "garment_name", "garment"),
                meta=meta if isinstance(meta, dict) else {},
                rest_vertices=d["rest_vertices"] if "rest_vertices" in d.files else None,
            )
            return cls(motion, garment, gv, avatar, npz_text(d, path, "source", "unknown"))
        except LoosefitInputError as exc:
            raise LoosefitInputError(path, exc.field, exc.expected, exc.found, exc.hint) from exc
        except (TypeError, ValueError) as exc:
            raise LoosefitInputError(path, "<fields>", "a loosefit sequence", str(exc)) from exc


_FIELDS = (
    "joint_names rotations root_translation fps vertices faces uvs face_uvs waist "
    "garment_vertices avatar"
).split()
