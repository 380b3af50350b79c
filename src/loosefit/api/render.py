"""Rendering through the API: a body and its garment through a motion to an MP4, PNG frames
and a contact sheet (offscreen, moderngl on EGL); what to draw: a garment placed on the
avatar (carried rigidly by its hips with :func:`loosefit.api.garment.carry_rigidly`), or a
stored clip (a sequence file, a data set's clip).

::

    from loosefit.api import motion_for
    from loosefit.api.garment import carry_rigidly
    from loosefit.api.motion import build_avatar
    from loosefit.api.render import garment_template, render_clip

    avatar = build_avatar()
    motion = motion_for("spin", avatar, 30.0, frames=60)
    skirt = garment_template("flared", avatar=avatar)
    body = avatar.pose_motion(motion)
    garment = carry_rigidly(skirt, body, avatar)
    render_clip("out", avatar=avatar, motion=motion, template=skirt, garment=garment,
                body=body, title="spin")

Each function imports what it needs when called.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

VIEWS = ("front", "three_quarter", "side")  # the camera views a render shows by default


def render_clip(
    out: str | Path,
    *,
    avatar,
    motion,
    title: str,
    template=None,
    garment: np.ndarray | None = None,
    body=None,
    size: int = 480,
    views: Sequence[str] = VIEWS,
    follow: bool = True,
    png_every: int = 0,
):
    """The body (and the garment, if any) through a motion, rendered into the folder
    ``out``: ``video.mp4``, ``video_sheet.png`` (a contact sheet) and, with ``png_every``,
    every Nth frame as ``frames/frame_NNNNN.png`` (:func:`loosefit.render.clip.render_clip`).

    Args:
        out: the folder (it must exist).
        avatar: the avatar the motion plays on (:func:`loosefit.api.motion.build_avatar`).
        motion: the :class:`~loosefit.types.Motion` of T frames; its fps is the video's.
        title: the text over the frames.
        template: the :class:`~loosefit.types.GarmentTemplate` drawn, or None: the body alone.
        garment: (T, V, 3) the garment's world positions, with ``template``.
        body: the posed body (``avatar.pose_motion(motion)``) where the caller has it;
            None: posed here.
        size: pixels per view (square).
        views: the camera views, side by side (``front``, ``three_quarter``, ``side``, ...).
        follow: the camera follows the dancer; False: frames the whole path once.
        png_every: also save every Nth frame as a PNG (0: none).

    Returns:
        the files written: ``video``, ``sheet`` (None where none was written).
    """
    from loosefit.render.clip import render_clip as render
    from loosefit.render.renderer import RenderConfig, RenderMesh

    body = body if body is not None else avatar.pose_motion(motion)
    scene = [
        RenderMesh(avatar.faces.cpu().numpy(), body.vertices.cpu().numpy(), "body", name="body")
    ]
    if template is not None:
        scene.append(RenderMesh(template.faces, garment, "garment", name=template.name))
    config = RenderConfig(width=size, height=size, views=tuple(views), follow=follow)
    return render(scene, out, fps=motion.fps, config=config, title=title, png_every=png_every)


def render_garments(
    out: str | Path,
    *,
    faces: np.ndarray,
    vertices: np.ndarray,
    title: str,
    fps: float = 4.0,
    size: int = 384,
    views: Sequence[str] = ("front", "side"),
    follow: bool = False,
    png_every: int = 1,
):
    """Garments alone (no body), one a frame, rendered into the folder ``out`` as
    :func:`render_clip` does (``video.mp4``, ``video_sheet.png``, PNG frames).

    Args:
        out: the folder (it must exist).
        faces: (F, 3) the garment's triangles.
        vertices: (T, V, 3) its world positions, frame by frame.
        title: the text over the frames.
        fps: the video's frame rate.
        size: pixels per view (square).
        views: the camera views, side by side.
        follow: the camera follows the garment; False: frames them all once.
        png_every: also save every Nth frame as a PNG (0: none).
    """
    from loosefit.render.clip import render_clip as render
    from loosefit.render.renderer import RenderConfig, RenderMesh

    scene = [RenderMesh(faces, vertices, "garment", name="garment")]
    config = RenderConfig(width=size, height=size, views=tuple(views), follow=follow)
    return render(scene, out, fps=fps, config=config, png_every=png_every, title=title)


def garment_template(spec: str, *, avatar, resolution: str = "cpu", length: float | None = None):
    """A garment on the avatar's rest pose (:func:`loosefit.fitting.place.garment_for`): a
    :class:`~loosefit.types.GarmentTemplate`, or None for ``"none"``.

    Args:
        spec: a skirt style (``aline``, ``flared``, ``circle``), ``dress``, a garment file
            (``.obj``), or ``none``.
        avatar: the avatar it is fitted to (:func:`loosefit.api.motion.build_avatar`).
        resolution: a made garment's mesh resolution (``cpu``, ``paper``).
        length: a made skirt's length in metres (None: its style's).

    Raises:
        LoosefitInputError: an unknown style or an unreadable file.
    """
    from loosefit.fitting.place import garment_for

    return garment_for(spec, avatar, resolution, length)


@dataclass
class StoredClip:
    """A clip read from disk to render.

    Attributes:
        sequence: the :class:`~loosefit.sequence.GarmentSequence` (motion, garment, body).
        label: what it is called: the file's stem, or ``DATASET/CLIP``.
    """

    sequence: object
    label: str


def read_stored_clip(
    *, sequence: str | Path | None = None, dataset: str | Path | None = None, clip=None
) -> StoredClip:
    """A sequence ``.npz`` (an animated garment's file or a data set's clip), or a clip of
    a data set folder (``clip``: its name; None: the first), complete or not.

    Raises:
        LoosefitInputError: neither or an unreadable file or folder.
    """
    from loosefit.data.format import DatasetReader, read_any_sequence
    from loosefit.errors import LoosefitInputError

    if sequence:
        return StoredClip(read_any_sequence(sequence), Path(sequence).stem)
    if not dataset:
        raise LoosefitInputError("read_stored_clip", "arguments", "sequence or dataset", "none")
    reader = DatasetReader(dataset, allow_incomplete=True)
    name = clip or reader.split("all")[0]
    return StoredClip(reader.read(name), f"{Path(dataset).name}/{name}")
