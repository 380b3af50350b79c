"""Garments through the API: a garment file placed on the avatar, or fitted to it when it was
made for another body (pushed out and draped, :mod:`loosefit.fitting.drape`); a garment
written as OBJ and template, and a picture of a fitted one; a garment carried rigidly by a
moving body, kept as a sequence (its exports then use the body already posed). Each imports
what it needs when called.

::

    from loosefit.api.garment import fit_config, garment_from_file, save_garment

    placed = garment_from_file("made_for_another.obj", fit=fit_config(), shape="auto")
    save_garment(placed.template, "out/garment")  # out/garment/made_for_another.obj, .npz
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path


@dataclass
class GarmentOnAvatar:
    """A garment file on the avatar's rest pose (:func:`garment_from_file`).

    Attributes:
        template: the garment (a :class:`~loosefit.types.GarmentTemplate`, V vertices,
            metres, Z up); its ``meta["import"]`` is ``report``.
        report: what the import guessed and did: ``units``, ``up``, ``kind`` (each with
            ``value`` and ``guessed``), ``placement``, ``attachment``, ``uv_source``.
        fit: what fitting did (:class:`~loosefit.fitting.drape.FitReport`); None when the
            file was only placed.
        avatar: the body it is on (simulate it on this one).
    """

    template: object
    report: dict
    fit: object | None
    avatar: object


def fit_config(**fields):
    """How a garment made for another body is fitted
    (:class:`~loosefit.fitting.drape.FitConfig`), e.g. ``settle_seconds=0.5`` (seconds of
    drape on the avatar standing still), checked.

    Raises:
        LoosefitInputError: a field out of its range (naming it).
    """
    from loosefit.fitting.drape import FitConfig

    return FitConfig(**fields)


def garment_from_file(
    path: str | Path,
    avatar=None,
    *,
    fit=None,
    shape: dict | str | None = None,
    units: str | None = None,
    up: str | None = None,
    kind: str | None = None,
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0),
    attach: str = "auto",
    bars: bool = False,
) -> GarmentOnAvatar:
    """A garment file (``.obj``, ``.gltf``, ``.glb``, in any units and axes) on the avatar's
    rest pose: placed (:func:`~loosefit.fitting.place.import_garment`, refused if it is
    inside the body), or, with ``fit``, fitted: pushed out of the body keeping its shape
    (Eq. 16) and draped there (:func:`~loosefit.fitting.drape.fit_garment`).

    Args:
        path: the garment file.
        avatar: the body (an :class:`~loosefit.body.avatar.Avatar`); None with ``fit``:
            ``shape``'s.
        fit: how it is fitted (:func:`fit_config`); None: placed only (``avatar`` needed).
        shape: with ``fit`` and no ``avatar``: the avatar's phenotype (anny's names; None:
            the project's avatar), or ``"auto"``: the body the garment fits best.
        units, up, kind, offset, attach: how the file is read and placed: its unit and up
            axis (None: guessed), ``skirt`` or ``dress`` (None: a dress if it has straps),
            metres to move it by after placement, what the simulation holds.
        bars: with ``fit``, a progress bar per stage of the fit on standard error.

    Returns:
        :class:`GarmentOnAvatar`: the template, the import's report, the fit's, the avatar.

    Raises:
        LoosefitInputError: an unreadable file or a bad option, a garment inside the body
            (placed only) or one that cannot be fitted (far from the body, closed).
    """
    if fit is None:
        from loosefit.fitting.place import import_garment

        template, report = import_garment(path, avatar, units, up, kind, offset, attach=attach)
        return GarmentOnAvatar(template, report, None, avatar)
    from loosefit.fitting.drape import STAGE_UNITS, fit_garment
    from loosefit.progress import StageBars

    stage_bars = StageBars("fit", STAGE_UNITS) if bars else None
    try:
        fitted = fit_garment(
            path,
            shape,
            fit,
            units,
            up,
            kind,
            offset=offset,
            attach=attach,
            avatar=avatar,
            progress=stage_bars.progress if stage_bars else None,
        )
    finally:
        if stage_bars is not None:
            stage_bars.close()
    template = fitted.template
    return GarmentOnAvatar(template, template.meta["import"], fitted.report, fitted.avatar)


def save_garment(template, out: str | Path, name: str | None = None) -> tuple[Path, Path]:
    """A garment written into the folder ``out`` (made if missing) as ``NAME.obj`` (its
    mesh and UVs, :func:`~loosefit.garment.obj.write_obj`) and ``NAME.npz`` (the template,
    waistband and meta included, :meth:`~loosefit.types.GarmentTemplate.load` reads it).

    Args:
        template: the :class:`~loosefit.types.GarmentTemplate`.
        out: the folder.
        name: the files' stem (default: the template's name).

    Returns:
        The OBJ's path and the template's.
    """
    from loosefit.garment.obj import write_obj

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    name = name or template.name
    obj, npz = out / f"{name}.obj", out / f"{name}.npz"
    write_obj(obj, template.vertices, template.faces, template.uvs, template.face_uvs)
    template.save(npz)
    return obj, npz


def fit_preview(path: str | Path, template, fit, avatar, *, size: int = 480):
    """A front and a side picture of a fitted garment on the avatar's rest pose, standing on
    the floor, titled with the fit's figures, written as a PNG at ``path``
    (:func:`~loosefit.render.clip.render_still`).

    Args:
        path: the PNG (its folder must exist).
        template: the fitted garment (V vertices, the avatar's rest frame).
        fit: its :class:`~loosefit.fitting.drape.FitReport` (``inside_after``,
            ``moved_max``).
        avatar: the body it was fitted to.
        size: pixels per view (square).

    Returns:
        The (size, 2 * size, 3) uint8 image written.

    Raises:
        RuntimeError: nothing can render here (no OpenGL context); nothing is written.
    """
    import numpy as np

    from loosefit.render.clip import render_still
    from loosefit.render.renderer import RenderConfig, RenderMesh

    up = np.array([0.0, 0.0, avatar.floor_height], np.float32)  # the rest pose's feet on z = 0
    body = avatar.rest_vertices.float().cpu().numpy() + up
    scene = [
        RenderMesh(avatar.faces.cpu().numpy(), body, "body", name="body"),
        RenderMesh(template.faces, template.vertices + up, "garment", name=template.name),
    ]
    title = (
        f"{template.name} fitted: {fit.inside_after} of {template.num_vertices} vertices "
        f"inside the body, moved by at most {100 * fit.moved_max:.1f} cm"
    )
    config = RenderConfig(width=size, height=size, views=("front", "side"), frame_counter=False)
    return render_still(scene, path, config, title)


def carry_rigidly(template, body, avatar, *, joint: str = "Hips"):
    """The garment moved rigidly with one joint of a posed body, no cloth dynamics
    (:func:`~loosefit.fitting.place.carry_rigidly`): what the simulation and the model
    improve on.

    Args:
        template: the garment on the avatar's rest pose (V vertices).
        body: the posed body (``avatar.pose_motion(motion)``, T frames).
        avatar: the avatar that posed it.
        joint: the joint the garment follows.

    Returns:
        (T, V, 3) numpy garment vertices (of the body's float type), world frame.
    """
    from loosefit.fitting.place import carry_rigidly as carry

    return carry(template, body, avatar, joint).cpu().numpy()


def dressed_sequence(motion, template, garment_vertices, avatar, source: str, *, body=None):
    """The garment's motion on the avatar as one sequence to save, export, render and view:
    a :class:`~loosefit.api.AnimatedGarment` recording the avatar's rig and shape.

    Args:
        motion: the body's motion (T frames).
        template: the garment (V vertices).
        garment_vertices: (T, V, 3) its world positions.
        avatar: the avatar the motion was posed on.
        source: what made the garment's motion (``"rigid"``, ``"newton-vbd"``, a model).
        body: the avatar already posed through ``motion`` (``avatar.pose_motion(motion)``),
            kept for the sequence's exports and body (None: posed again when first asked for).
    """
    from loosefit.api import AnimatedGarment

    record = {"rig": avatar.config.rig, "shape": dict(avatar.shape)}
    sequence = AnimatedGarment(motion, template, garment_vertices, record, source)
    if body is not None:
        sequence.keep_body(avatar, body)
    return sequence
