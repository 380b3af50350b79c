"""The trained set's garment on a user's own character.

:func:`dress_character`:

1. reads the character (:func:`~loosefit.character.gltf_character.read_character`) and its
   animation retargeted onto anny (:func:`~loosefit.motion.motions.load_motion`);
2. fits anny's phenotype to the character's skin in its first frame
   (:func:`~loosefit.character.fit_body.fit_body`), refusing a character anny cannot fit;
3. animates the garment on the fitted anny (the trained set on another body,
   :mod:`loosefit.inference.other_body`), without collision handling;
4. carries it from anny's skin onto the character's own skin, frame by frame
   (:func:`~loosefit.inference.other_body.carry_garment`; each anny anchor follows the
   closest point of the character's skin in the first frame, by its triangle and
   barycentric weights);
5. runs collision handling against the character's mesh itself.

Positions: anny's frame is the motion's (avatar axes, Z up); the character's skin lies in
it turned by the retargeting's axis change C and moved so that its hips sit where anny's
do in every frame. :class:`DressedCharacter` gives the garment back in the character's
glTF world (metres, Y up), and writes it beside the character
(:meth:`DressedCharacter.export`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from loosefit.character.fit_body import BodyFit, FitLimits, fit_body
from loosefit.character.gltf_character import Character, read_character
from loosefit.errors import LoosefitInputError
from loosefit.export.meshes import Z_TO_Y_UP
from loosefit.inference.other_body import OtherBody, carry_garment
from loosefit.types import GarmentTemplate, Motion


@dataclass
class DressedCharacter:
    """A character with the garment on it.

    Attributes:
        character: the character read from its file.
        fit: anny's body fitted to it.
        body: the fitted anny, prepared (its garment, its anchors).
        motion: the character's animation on the fitted anny (T frames).
        garment: the garment's template (sized to the fitted body).
        vertices: (T, V, 3) the garment in the character's glTF world (m, Y up).
        anny_frame: (T, V, 3) the same garment in anny's frame, on the fitted anny's motion.
        collisions: per frame, collision handling's figures against the character's mesh.
    """

    character: Character
    fit: BodyFit
    body: OtherBody
    motion: Motion
    garment: GarmentTemplate
    vertices: np.ndarray
    anny_frame: np.ndarray
    collisions: list[dict]

    @property
    def fps(self) -> float:
        return float(self.motion.fps)

    def z_up(self) -> np.ndarray:
        """(T, V, 3) the garment in the character's world as Z up (what a glTF importer
        such as Blender's shows, and what loosefit's exporters take)."""
        return self.vertices @ Z_TO_Y_UP

    def sequence(self, source: str = "loosefit"):
        """The garment on the fitted anny as an
        :class:`~loosefit.sequence.GarmentSequence` (what ``loosefit view`` and ``render``
        show; anny's frame)."""
        from loosefit.sequence import GarmentSequence

        record = {"rig": self.body.avatar.config.rig, "shape": dict(self.body.shape)}
        return GarmentSequence(self.motion, self.garment, self.anny_frame, record, source)

    def export(self, path: str | Path) -> list[Path]:
        """Write the garment beside the character.

        ``.glb``: the character's own file (its meshes, skin, animation and everything
        else untouched) with the garment added as a mesh animated on the same timeline;
        ``.usd``/``.usda``/``.usdc``, ``.abc``, ``.pc2`` or a folder (OBJ per frame): the
        garment alone, in the character's world.
        """
        from loosefit.character.gltf_merge import add_animated_mesh
        from loosefit.export import check_export_path, export_animation
        from loosefit.export.meshes import AnimatedMesh

        path = check_export_path(path)
        g = self.garment
        mesh = AnimatedMesh("garment", g.faces, self.z_up(), g.uvs, g.face_uvs, normals=True)
        if path.suffix.lower() == ".glb":
            return [add_animated_mesh(self.character, mesh, path)]
        return export_animation(path, [mesh], self.fps)


@dataclass
class FittedCharacter:
    """A character and the anny body fitted to it (:func:`fit_character`).

    Attributes:
        character: the character read from its file.
        fit: anny's phenotype and the misfit.
        axes: (3, 3) C, the retargeting's turn of the file's axes onto anny's.
        hips: the character's joint that anny's hips follow.
        skin0: (V, 3) the character's skin in its first frame, turned by C (anny's axes).
        anny0: (Va, 3) the fitted anny in the same pose, on the character's skin.
    """

    character: Character
    fit: BodyFit
    axes: np.ndarray
    hips: str
    skin0: np.ndarray
    anny0: np.ndarray


def fit_character(
    model, path: str | Path, limits: FitLimits | None = None, retarget=None
) -> FittedCharacter:
    """The character of ``path`` read and anny's body fitted to it
    (:func:`~loosefit.character.fit_body.fit_body`).

    Raises:
        LoosefitInputError: a file with no mesh, skin or animation; a character anny cannot
            fit (the misfit measured).
    """
    from loosefit.body.avatar import Avatar, AvatarConfig

    path = Path(path)
    trained = model.avatar()
    character = read_character(path, model.fps)
    axes, hips = _axes_and_hips(path, model.fps, retarget)
    first = _motion(path, trained, model.fps, retarget, 1)
    skin0 = character.posed(0, 1)[0] @ axes.T
    hips0 = axes @ character.joint_world(hips)[0]
    fit = fit_body(
        skin0,
        character.faces,
        hips0,
        first.rotations[0],
        trained,
        limits=limits or FitLimits(),
        source=str(path),
    )
    fitted = Avatar(AvatarConfig(rig=trained.config.rig, shape=fit.shape))
    motion0 = _motion(path, fitted, model.fps, retarget, 1)
    posed = fitted.pose_motion(motion0)
    anny0 = posed.vertices[0].double().cpu().numpy()
    anny0 = anny0 - posed.joint_poses[0, 0, :3, 3].double().cpu().numpy() + hips0 + fit.offset
    return FittedCharacter(character, fit, axes, hips, skin0, anny0)


def dress_character(
    model,
    path: str | Path,
    frames: int | None = None,
    progress=None,
    limits: FitLimits | None = None,
    retarget=None,
) -> DressedCharacter:
    """The trained set's garment on the character of a skinned, animated glTF.

    Args:
        model: the trained set (an :class:`~loosefit.inference.animator.AnimationModel`).
        path: the character's ``.gltf``/``.glb``.
        frames: the first frames only (None: all).
        progress: ``progress(done, total)`` of the rollout.
        limits: the fit's misfit refused (default :class:`FitLimits`).
        retarget: how its animation is read (:class:`~loosefit.motion.retarget.RetargetConfig`).

    Raises:
        LoosefitInputError: a file with no mesh, skin or animation, a character anny cannot
            fit (the misfit measured), a model that cannot change body (a baseline).
    """
    from loosefit.inference.stages import Stages

    if not hasattr(model, "other_body"):
        raise LoosefitInputError(
            path, "model", "our model (a baseline animates on its own body)", type(model).__name__
        )
    path = Path(path)
    fitted = fit_character(model, path, limits, retarget)
    character, fit, axes = fitted.character, fitted.fit, fitted.axes
    body = model.other_body(fit.shape)
    motion = _motion(path, body.avatar, model.fps, retarget, frames)
    T = min(motion.num_frames, character.num_frames)
    motion = motion.slice(0, T)
    # the character's skin in anny's frame: turned by C, its hips where anny's are
    hips = character.joint_world(fitted.hips)[:T] @ axes.T
    shift = motion.root_translation - hips - fit.offset
    stages = Stages(collision=False, overlap=False)
    result = model.animate(motion, progress, stages=stages, body=body)

    def skin(start: int, stop: int) -> np.ndarray:
        return character.posed(start, stop) @ axes.T + shift[start:stop, None]

    on_anny = torch.from_numpy(result.vertices).float()
    carried = _carry(body, motion, on_anny, skin, character.faces)
    placed, collisions = _collide(model, body, carried, skin, character.faces)
    vertices = (placed - shift[:, None]) @ axes  # back to the character's glTF world
    return DressedCharacter(
        character, fit, body, motion, body.template, vertices, placed, collisions
    )


def _motion(path: Path, avatar, fps: float, retarget, frames: int | None) -> Motion:
    from loosefit.motion.motions import load_motion

    motion = load_motion(str(path), avatar, fps=fps, retarget=retarget)
    return motion if frames is None else motion.slice(0, min(frames, motion.num_frames))


def _axes_and_hips(path: Path, fps: float, retarget) -> tuple[np.ndarray, str]:
    """The retargeting's axis change C (file axes to the avatar's) and the character's joint
    it maps onto anny's hips."""
    from loosefit.motion.gltf import read_gltf
    from loosefit.motion.retarget import (
        RetargetConfig,
        axis_change,
        resolve_joint_map,
        source_axes,
    )

    config = retarget or RetargetConfig()
    clip = read_gltf(path, fps=fps)
    jmap = resolve_joint_map(clip, config).joint_map
    up, forward, _ = source_axes(clip, config, jmap)
    return axis_change(up, forward).astype(np.float64), jmap.joints["Hips"]


def _carry(body: OtherBody, motion: Motion, garment: torch.Tensor, skin, faces) -> np.ndarray:
    """(T, V, 3) the garment carried from the fitted anny onto the character's skin."""
    from loosefit.geometry.query import closest_points

    anchors0 = body.anchors_along(body.avatar, motion, 0, 1)[0].double().numpy()
    hit = closest_points(skin(0, 1)[0], faces, anchors0, max_distance=10.0)
    corners = faces[hit.faces]  # (A, 3) the character's triangle under each anchor
    out = np.empty(garment.shape, np.float32)
    for s in range(0, len(garment), 64):
        e = min(s + 64, len(garment))
        verts = skin(s, e)  # (n, Vc, 3)
        to = np.einsum("nakx,ak->nax", verts[:, corners], hit.barycentric)
        moved = carry_garment(
            garment[s:e],
            body.anchors_along(body.avatar, motion, s, e),
            torch.from_numpy(to).float(),
            body.config,
        )
        out[s:e] = moved.numpy()
    return out


def _collide(model, body: OtherBody, garment: np.ndarray, skin, faces):
    """Collision handling of every frame against the character's own mesh."""
    from loosefit.inference.stages.collision import (
        BodyCollider,
        CollisionHandler,
        collision_record,
    )

    t = body.template
    if body.handler is None:
        rest = np.asarray(t.vertices, np.float64)
        body.handler = CollisionHandler(t.faces, t.num_vertices, model.collision, rest)

    def pose(start: int, stop: int) -> np.ndarray:
        return skin(start, stop).astype(np.float32)

    collide = BodyCollider(body.handler, faces, pose, len(garment))
    out, records = np.empty_like(garment), []
    for i in range(len(garment)):
        result = collide(i, torch.from_numpy(garment[i]).to(model.device))
        out[i] = result.vertices.cpu().numpy()
        records.append(collision_record(result))
    return out, records
