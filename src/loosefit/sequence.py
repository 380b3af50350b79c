"""A dressed animation on disk.

It holds the motion, the avatar's shape, the garment template and its vertices.

The body is not stored: it is reproduced exactly by posing the avatar (same
rig and shape) with the motion, which keeps a file ~20x smaller than storing
body meshes. Files are plain ``.npz`` (readable with numpy alone); every field
is validated when read.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from loosefit.atomic import atomic_path
from loosefit.errors import LoosefitInputError
from loosefit.types import GarmentTemplate, Motion

FORMAT = "loosefit.sequence/1"


@dataclass
class AnimatedGarment:
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

    def _pose_body(self) -> None:
        from loosefit.body.avatar import Avatar, AvatarConfig

        config = AvatarConfig(rig=self.avatar.get("rig", "cmu_mb"),
                              shape=dict(self.avatar.get("shape", {})))  # fmt: skip
        avatar = Avatar(config)
        self._body = avatar.pose_motion(self.motion).vertices.cpu().numpy()
        self._body_faces = avatar.faces.cpu().numpy()

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

    def export(self, path: str | Path, body: bool = True) -> list[Path]:
        """Write the garment (and the body) in the format ``path``'s suffix names:
        ``.usd``/``.usdc``/``.usda``, ``.pc2`` (+ OBJ), or a folder of OBJs
        (:func:`loosefit.export.export_animation`)."""
        from loosefit.export import export_animation, garment_and_body

        meshes = garment_and_body(self.garment, self.garment_vertices,
                                  self.body_vertices if body else None,
                                  self.body_faces if body else None)  # fmt: skip
        return export_animation(path, meshes, self.fps)

    def __post_init__(self) -> None:
        self.garment_vertices = np.asarray(self.garment_vertices, dtype=np.float32)
        T, V = self.motion.num_frames, self.garment.num_vertices
        gv = self.garment_vertices
        if gv.shape != (T, V, 3):
            raise LoosefitInputError(
                "AnimatedGarment", "garment_vertices", f"shape ({T}, {V}, 3)", f"{gv.shape}"
            )
        bad = ~np.isfinite(gv)
        if bad.any():
            t = int(np.argwhere(bad)[0][0])
            raise LoosefitInputError(
                "AnimatedGarment", "garment_vertices", "finite values", f"NaN/inf from frame {t}"
            )

    def save(self, path: str | Path) -> Path:
        """Write atomically to ``path`` (``.npz``)."""
        path = Path(path)
        with atomic_path(path) as tmp:
            np.savez(
                tmp,
                format=np.array(FORMAT),
                joint_names=np.array(self.motion.joint_names),
                rotations=self.motion.rotations,
                root_translation=self.motion.root_translation,
                fps=np.float64(self.motion.fps),
                motion_name=np.array(self.motion.name),
                vertices=self.garment.vertices,
                faces=self.garment.faces,
                uvs=self.garment.uvs,
                face_uvs=self.garment.face_uvs,
                waist=self.garment.waist,
                garment_name=np.array(self.garment.name),
                garment_vertices=self.garment_vertices,
                avatar=np.array(json.dumps(self.avatar)),
                source=np.array(self.source),
            )
        return path

    @classmethod
    def load(cls, path: str | Path) -> AnimatedGarment:
        """Read and validate a file written by :meth:`save`."""
        path = Path(path)
        if not path.is_file():
            raise LoosefitInputError(path, "<file>", "an existing .npz sequence", "no such file")
        try:
            d = np.load(path, allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise LoosefitInputError(path, "<file>", "a .npz sequence", str(exc)) from exc
        fmt = str(d["format"]) if "format" in d.files else "none"
        if fmt != FORMAT:
            raise LoosefitInputError(path, "format", repr(FORMAT), repr(fmt))
        need = (
            "joint_names rotations root_translation fps vertices faces uvs face_uvs waist "
            "garment_vertices avatar"
        ).split()
        missing = [k for k in need if k not in d.files]
        if missing:
            raise LoosefitInputError(path, ", ".join(missing), "present", "missing")
        try:
            motion = Motion(
                tuple(str(n) for n in d["joint_names"]),
                d["rotations"],
                d["root_translation"],
                float(d["fps"]),
                str(d["motion_name"]) if "motion_name" in d.files else path.stem,
            )
            garment = GarmentTemplate(
                d["vertices"], d["faces"], d["uvs"], d["face_uvs"], d["waist"],
                name=str(d["garment_name"]) if "garment_name" in d.files else "garment",
            )  # fmt: skip
            return cls(
                motion,
                garment,
                d["garment_vertices"],
                json.loads(str(d["avatar"])),
                str(d["source"]) if "source" in d.files else "unknown",
            )
        except LoosefitInputError as exc:
            raise LoosefitInputError(path, exc.field, exc.expected, exc.found, exc.hint) from exc


DressedSequence = AnimatedGarment  # the earlier name
