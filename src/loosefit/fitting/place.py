"""Dressing the avatar: garments fitted to it, garments from files placed on it, and a
garment carried by the body.

* :func:`fit_skirt` and :func:`fit_dress`: the parametric garments, made for the body.
* :func:`import_garment`: a user's file in its own units and axes, converted, placed on
  the body (:func:`place_garment`), given its attachment and UVs, and checked to hang
  clear of the body.
* :func:`check_fitted_shape`: a garment fitted to a body (:mod:`loosefit.fitting.drape`, which
  drapes it in the simulator above this layer) is used on that body only.

Everything here is in the avatar's rest frame (root joint at the origin, see
:class:`~loosefit.body.avatar.Avatar`) unless a function says otherwise.

Placement rules (the same for a parametric garment and a file, so that a dress exported
and imported again lands where it was made):

* a skirt: the centre of its top opening (the waistband) on the body's axis at the
  natural waist, at the natural waist's height;
* a dress with straps (more than two openings): the centre of its neckline on the
  body's axis at the chest, its highest point :data:`STRAP_CLEARANCE` over the shoulders;
* a strapless dress: the centre of its top opening on the body's axis at the chest, at
  the chest's height (:func:`chest_height`, under the arms).
"""

from __future__ import annotations

import numpy as np
import torch

from loosefit.body.avatar import DEFAULT_SHAPE, Avatar, BodySequence
from loosefit.errors import LoosefitInputError
from loosefit.garment.dress import DRESS_SPECS, DressConfig, DressFit, make_dress
from loosefit.garment.skirt import SkirtConfig, make_skirt
from loosefit.garment.waist_fit import waist_fit_from_points
from loosefit.types import GarmentTemplate

TORSO_BONES = ("Hips", "LowerBack", "Spine", "LHipJoint", "RHipJoint")
HIP_BONES = TORSO_BONES + ("LeftUpLeg", "RightUpLeg", "LeftLeg", "RightLeg")
# the body a dress covers: the torso up to the neck, the hips and legs (no arms)
DRESS_BONES = HIP_BONES + ("Spine1", "LeftShoulder", "RightShoulder", "Neck")
STRAP_CLEARANCE = 0.006  # m, a strap's top over the shoulder's skin
ARMPIT_GAP = 0.045  # m, the chest line is where the arms hang this far from the torso
ATTACH_DEPTH = 0.03  # m, a strap dress is held by its vertices this close to its top
FIT_REACH = 0.1  # m, the deepest a vertex may be inside the body and be pushed out by
#   fitting (loosefit.fitting.drape.FitConfig.reach's default)


def natural_waist_height(avatar: Avatar, step: float = 0.005, band: float = 0.01) -> float:
    """Height (rest frame) of the narrowest torso cross-section between lower back and mid-spine.

    Args:
        avatar: the body.
        step: spacing of the heights tried, metres.
        band: half-thickness of each horizontal slab, metres.
    """
    pts = avatar.rest_vertices[avatar.vertices_of_bones(TORSO_BONES)].double().cpu().numpy()
    heads = _joint_heads(avatar)
    lo, hi = heads["LowerBack"][2], 0.5 * (heads["Spine"][2] + heads["Spine1"][2])
    best, best_w = lo, np.inf
    for z in np.arange(lo, hi, step):
        slab = pts[np.abs(pts[:, 2] - z) <= band]
        if len(slab) < 8:
            continue
        width = np.ptp(slab[:, 0]) + np.ptp(slab[:, 1])
        if width < best_w:
            best, best_w = float(z), width
    return best


def fit_skirt(
    avatar: Avatar, config: SkirtConfig | None = None, waist_offset: float = 0.0
) -> GarmentTemplate:
    """A skirt whose waistband fits the avatar's natural waist and whose rest shape clears its hips.

    Args:
        avatar: the body (rest frame: root joint at the origin).
        config: the skirt's style, length and resolution (default: the CPU A-line).
        waist_offset: metres to move the waistband up (+) or down (-) from the natural waist.

    Returns:
        The :class:`GarmentTemplate` in the avatar's rest frame.
    """
    config = config or SkirtConfig.preset("cpu", "aline")
    height = natural_waist_height(avatar) + waist_offset
    pts = avatar.rest_vertices[avatar.vertices_of_bones(HIP_BONES)].double().cpu().numpy()
    fit = waist_fit_from_points(
        pts, height, max_radius=0.3, profile_depth=min(config.length, 0.6), profile_rows=24
    )
    skirt = make_skirt(config, fit)
    skirt.meta["waist_height_rest_frame"] = height
    return skirt


def carry_rigidly(
    template: GarmentTemplate, body: BodySequence, avatar: Avatar, joint: str = "Hips"
) -> torch.Tensor:
    """The garment moved rigidly with one joint: no cloth dynamics at all.

    This is what the demo shows before a simulation exists; it is also a
    baseline for what physics and learning must improve on.

    Args:
        template: the garment at the avatar's rest pose.
        body: the posed body (its ``joint_transforms`` map rest to posed).
        avatar: the avatar that ``body`` was posed with.
        joint: the joint the garment follows.

    Returns:
        (T, V, 3) garment vertices.
    """
    j = avatar.joint_names.index(joint)
    M = body.joint_transforms[:, j]  # (T, 4, 4)
    v = torch.from_numpy(template.vertices).to(M)
    return (M[:, None, :3, :3] @ v[None, :, :, None])[..., 0] + M[:, None, :3, 3]


def garment_for(
    spec: str, avatar: Avatar, resolution: str = "cpu", length: float | None = None
) -> GarmentTemplate | None:
    """A garment on the avatar's rest pose from a style name or a file.

    Args:
        spec: a skirt style (``aline``, ``flared``, ``circle``) or a dress (``dress``, with
            straps, or ``dress-strapless``), fitted to the avatar; a ``.obj``/``.gltf``/
            ``.glb`` file (:func:`import_garment`, units and axes guessed), a loosefit
            template ``.npz``; or ``none`` (no garment: None).
        avatar: the body.
        resolution: the skirt's mesh preset (``cpu`` 2,352 vertices, ``paper``).
        length: the skirt's length in metres (default: the style's).

    Raises:
        LoosefitInputError: another spec.
    """
    from loosefit.garment.skirt import STYLES

    extra = {} if length is None else {"length": length}
    if spec == "none":
        return None
    if spec in STYLES:
        return fit_skirt(avatar, SkirtConfig.preset(resolution, spec, **extra))
    if spec in DRESS_SPECS:
        return fit_dress(avatar, DressConfig.preset(resolution, DRESS_SPECS[spec], **extra))
    suffix = str(spec).lower().rsplit(".", 1)[-1]
    if suffix in ("obj", "gltf", "glb"):
        return import_garment(spec, avatar)[0]
    if suffix == "npz":
        template = GarmentTemplate.load(spec)
        check_fitted_shape(template, avatar, spec)  # a --fit garment: on the body it was fitted to
        return template
    raise LoosefitInputError(
        "garment",
        "value",
        f"one of {STYLES + tuple(DRESS_SPECS)}, 'none', or a .obj/.gltf/.glb/.npz file",
        repr(spec),
    )


# -- the body's landmarks -----------------------------------------------------------------------


def chest_height(avatar: Avatar, step: float = 0.005) -> float:
    """Height (rest frame) of the chest line under the arms: from the shoulders down, the
    first height where both arms hang :data:`ARMPIT_GAP` clear of the torso's sides."""
    v = avatar.rest_vertices.double().cpu().numpy()
    torso = v[
        avatar.vertices_of_bones(("Spine1", "Spine", "LeftShoulder", "RightShoulder", "LowerBack"))
        .cpu()
        .numpy()
    ]
    heads = _joint_heads(avatar)
    top, bottom = float(heads["LeftArm"][2]), float(heads["Spine"][2])
    arms = [
        (v[avatar.vertices_of_bones((arm,)).cpu().numpy()], sign)
        for arm, sign in (("LeftArm", 1.0), ("RightArm", -1.0))
    ]
    for z in np.arange(top, bottom, -step):
        gaps = []
        for arm, sign in arms:
            a, t = arm[np.abs(arm[:, 2] - z) <= 0.01], torso[np.abs(torso[:, 2] - z) <= 0.01]
            if len(a) == 0 or len(t) == 0:
                gaps.append(np.inf)
                continue
            gaps.append(float((sign * a[:, 0]).min() - (sign * t[:, 0]).max()))
        if min(gaps) >= ARMPIT_GAP:
            return float(z)
    return bottom


def _torso_centre(avatar: Avatar, height: float, band: float = 0.015) -> np.ndarray:
    """(2,) the middle of the torso's cross-section (no arms) at ``height``."""
    pts = avatar.rest_vertices[avatar.vertices_of_bones(DRESS_BONES)].double().cpu().numpy()
    slab = pts[np.abs(pts[:, 2] - height) <= band, :2]
    return 0.5 * (slab.min(0) + slab.max(0))


def _joint_heads(avatar: Avatar) -> dict:
    """Joint name -> (3,) its head at the rest pose."""
    return dict(zip(avatar.joint_names, avatar.skeleton.heads, strict=True))


def _shoulders(avatar: Avatar) -> tuple[float, float]:
    """Where straps go: their distance from the body's axis, and the shoulders' top there."""
    heads = _joint_heads(avatar)
    x = 0.6 * 0.5 * (float(heads["LeftArm"][0]) - float(heads["RightArm"][0]))
    bones = ("LeftShoulder", "RightShoulder", "Spine1", "Neck")
    v = avatar.rest_vertices[avatar.vertices_of_bones(bones)].double().cpu().numpy()
    near = v[np.abs(np.abs(v[:, 0]) - x) <= 0.01]
    return x, float(near[:, 2].max())


def push_out_of(avatar: Avatar, arms: bool | str = "upper", clearance: float = 0.008):
    """A function (N, 3) -> (N, 3) moving points inside the rest body (or closer to it than
    ``clearance``) to ``clearance`` outside it, along the surface's normal."""
    from loosefit.geometry.query import closest_points

    body = avatar.rest_vertices.double().cpu().numpy()
    faces = avatar.collider_faces(arms=arms).cpu().numpy()

    tri = body[faces]  # (Fb, 3, 3)
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    volume = (tri[:, 0] * normals).sum() / 6.0  # > 0: the faces wind outward
    normals *= np.sign(volume) / np.linalg.norm(normals, axis=1, keepdims=True)

    def push(points: np.ndarray) -> np.ndarray:
        points = np.asarray(points, np.float64).copy()
        for _ in range(3):  # a point pushed out of one part may land near another
            hit = closest_points(body, faces, points)
            close = hit.inside | (hit.distance < clearance)
            if not close.any():
                break
            points[close] = hit.points[close] + clearance * normals[hit.faces[close]]
        return points

    return push


# -- placement -------------------------------------------------------------------------------


def place_garment(
    vertices: np.ndarray, faces: np.ndarray, avatar: Avatar, kind: str, offset=(0.0, 0.0, 0.0)
) -> tuple[np.ndarray, dict]:
    """Move a garment (V, 3), Z up and in metres, onto the avatar by the module's rules.

    Args:
        vertices: (V, 3) positions; faces: (F, 3) its triangles.
        avatar: the body.
        kind: ``"skirt"`` or ``"dress"``.
        offset: (3,) metres added after placement (``--offset``).

    Returns:
        (V, 3) placed positions and what the placement did (the rule, the translation).

    Raises:
        LoosefitInputError: no top opening to place it by.
    """
    from loosefit.garment.importer import KINDS, top_opening
    from loosefit.garment.mesh_checks import boundary_loops

    if kind not in KINDS:
        raise LoosefitInputError("--kind", "kind", f"one of {KINDS}", repr(kind))
    v = np.asarray(vertices, np.float64)
    top = top_opening(v, faces)
    if top is None:
        raise LoosefitInputError(
            "garment", "openings", "a top opening round the body (a waistband, a neckline)", "none"
        )
    ring = v[top]
    seg = np.linalg.norm(np.roll(ring, -1, 0) - ring, axis=1)
    centre = ((ring + np.roll(ring, -1, 0)) * 0.5 * seg[:, None]).sum(0) / seg.sum()
    if kind == "skirt":
        rule, height = "waistband at the natural waist", natural_waist_height(avatar)
        now, axis = centre[2], _torso_centre(avatar, height)
    elif len(boundary_loops(faces)) > 2:
        rule, height = "top over the shoulders", _shoulders(avatar)[1] + STRAP_CLEARANCE
        now, axis = v[:, 2].max(), _torso_centre(avatar, chest_height(avatar))
    else:
        rule, height = "top band at the chest", chest_height(avatar)
        now, axis = centre[2], _torso_centre(avatar, height)
    shift = np.array([axis[0] - centre[0], axis[1] - centre[1], height - now])
    shift += np.asarray(offset, np.float64)
    return v + shift, {"rule": rule, "translation_m": shift.tolist()}


def attachment_of(
    vertices: np.ndarray, faces: np.ndarray, kind: str, attach: str | np.ndarray = "auto"
) -> tuple[np.ndarray, str]:
    """The vertices the simulation holds on the body, and how (``"loop"``: a closed band
    in order; ``"points"``).

    ``auto``: a skirt's or a strapless dress's top opening (the waistband, the top band);
    a dress with straps: its vertices within :data:`ATTACH_DEPTH` of its top (the straps
    over the shoulders). ``top``: the top opening whatever the kind. An index array, or a
    text file of them (:func:`read_indices`): those.

    Raises:
        LoosefitInputError: bad indices, or ``"none"`` (the simulation needs a hold).
    """
    from loosefit.garment.importer import top_opening
    from loosefit.garment.mesh_checks import boundary_loops

    v = np.asarray(vertices, np.float64)
    if isinstance(attach, str):
        if attach == "none":
            raise LoosefitInputError(
                "--attach",
                "attach",
                "auto, top, or a file of vertex indices",
                "'none'",
                hint="the simulation holds every garment by its attachment: a dress that only "
                "hangs on the body is not supported yet",
            )
        if attach not in ("auto", "top"):
            return attachment_of(vertices, faces, kind, read_indices(attach))
        straps = kind == "dress" and len(boundary_loops(faces)) > 2
        if attach == "auto" and straps:
            return np.flatnonzero(v[:, 2] >= v[:, 2].max() - ATTACH_DEPTH), "points"
        top = top_opening(v, faces)
        if top is None:
            raise LoosefitInputError("garment", "openings", "a top opening to attach", "none")
        return np.asarray(top, np.int64), "loop"
    idx = np.asarray(attach)
    if idx.ndim != 1 or len(idx) == 0 or idx.dtype.kind not in "iu":
        raise LoosefitInputError(
            "--attach",
            "attach",
            "a non-empty list of vertex indices",
            f"shape {idx.shape}, dtype {idx.dtype}",
        )
    if idx.min() < 0 or idx.max() >= len(v):
        raise LoosefitInputError(
            "--attach",
            "attach",
            f"vertex indices in [0, {len(v)})",
            f"range [{idx.min()}, {idx.max()}]",
        )
    return idx.astype(np.int64), "points"


def read_indices(path) -> np.ndarray:
    """Vertex indices from a text file (whitespace or comma separated)."""
    from pathlib import Path

    path = Path(path)
    if not path.is_file():
        raise LoosefitInputError(path, "attach", "a text file of vertex indices", "no such file")
    try:
        return np.array([int(t) for t in path.read_text().replace(",", " ").split()], np.int64)
    except ValueError as exc:
        raise LoosefitInputError(path, "attach", "integers", str(exc)) from exc


def collider_arms(template: GarmentTemplate) -> bool | str:
    """The arms a garment's collider needs: the upper arms for a dress (its bodice reaches
    them), none for a skirt."""
    return "upper" if (template.meta or {}).get("kind") == "dress" else False


def check_clear_of_body(template: GarmentTemplate, avatar: Avatar, source="garment") -> None:
    """Raise unless every vertex of ``template`` is outside the avatar's rest body (the
    collider the simulation would use).

    Raises:
        LoosefitInputError: naming how many vertices are inside, the deepest, its height
            and the body part it is in.
    """
    from loosefit.geometry.query import closest_points

    body = avatar.rest_vertices.double().cpu().numpy()
    faces = avatar.collider_faces(arms=collider_arms(template)).cpu().numpy()
    hit = closest_points(body, faces, template.vertices)
    inside = np.flatnonzero(hit.inside)
    if len(inside) == 0:
        return
    deepest = int(inside[np.argmax(hit.distance[inside])])
    corner = faces[hit.faces[deepest]][np.argmax(hit.barycentric[deepest])]
    weights = avatar.model.vertex_bone_weights[int(corner)]
    bone = avatar.joint_names[int(avatar.model.vertex_bone_indices[int(corner)][weights.argmax()])]
    raise LoosefitInputError(
        source,
        "placement",
        "a garment hanging clear of the body",
        f"{len(inside)} of {template.num_vertices} vertices inside it, the deepest (vertex "
        f"{deepest}, {100 * hit.distance[deepest]:.1f} cm in) at height "
        f"{template.vertices[deepest, 2]:.3f} m in the {bone}",
        hint=_fit_hint(source, template, avatar, float(hit.distance[deepest])),
    )


def _fit_hint(source, template: GarmentTemplate, avatar: Avatar, depth: float) -> str:
    """What to do about a garment ``depth`` m inside the body: ``garment FILE --fit`` first
    (the exact command: the options the import was given, the avatar's shape), when the push
    can reach its deepest vertex; then the import's options."""
    import shlex

    others = "check --units and --kind, or move it with --offset X,Y,Z (metres)"
    reach = FIT_REACH
    if depth > reach:  # --fit would refuse it too: the options first
        return f"{others} (--fit pushes out vertices no deeper than {100 * reach:.0f} cm)"
    command = f"loosefit garment {shlex.quote(str(source))} --fit"
    given = (template.meta or {}).get("import", {})
    for key in ("units", "up", "kind"):
        if key in given and not given[key]["guessed"]:
            command += f" --{key} {given[key]['value']}"
    if "offset_m" in given.get("placement", {}):
        command += " --offset=" + ",".join(f"{t:g}" for t in given["placement"]["offset_m"])
    if avatar.shape != DEFAULT_SHAPE:  # fitted to this body, not the default one
        command += " --shape " + ",".join(f"{k}={v:g}" for k, v in avatar.shape.items())
    return (
        f"made for another body? fit it to this one with `{command}` and use the .npz it "
        f"writes; or {others}"
    )


# -- garments ---------------------------------------------------------------------------------


def fit_dress(avatar: Avatar, config: DressConfig | None = None) -> GarmentTemplate:
    """A dress whose top band fits the avatar's chest and whose rest shape clears its body,
    placed by the module's rules (as an imported dress would be)."""
    config = config or DressConfig.preset("cpu", "straps")
    height = chest_height(avatar)
    pts = avatar.rest_vertices[avatar.vertices_of_bones(DRESS_BONES)].double().cpu().numpy()
    top = waist_fit_from_points(
        pts, height, max_radius=0.3, profile_depth=min(config.length, 1.0), profile_rows=48
    )
    strap_x, shoulder = _shoulders(avatar)
    fit = DressFit(
        top, strap_x, shoulder + STRAP_CLEARANCE, push_out_of(avatar, "upper", STRAP_CLEARANCE)
    )
    dress = make_dress(config, fit)
    placed, info = place_garment(dress.vertices, dress.faces, avatar, "dress")
    dress.vertices = placed.astype(np.float32)
    dress.meta["placement"] = info
    return dress


def import_garment(
    path,
    avatar: Avatar,
    units: str | None = None,
    up: str | None = None,
    kind: str | None = None,
    offset=(0.0, 0.0, 0.0),
    *,
    attach: str | np.ndarray = "auto",
    name: str | None = None,
    check: bool = True,
) -> tuple[GarmentTemplate, dict]:
    """A user's garment file as a template on the avatar.

    Args:
        path: ``.obj``, ``.gltf`` or ``.glb``: one manifold piece of cloth, wound
            counter-clockwise seen from outside.
        avatar: the body.
        units: the file's unit (:data:`~loosefit.garment.importer.UNITS`); None: guessed
            from the garment's size.
        up: the file's up axis (``z``, ``y``, ``-z``, ``-y``); None: guessed from its
            openings.
        kind: ``skirt`` or ``dress``; None: a dress if it has more than two openings.
        offset: (3,) metres to move it by after placement.
        attach: what the simulation holds (:func:`attachment_of`).
        name: the template's name (default: the file's stem).
        check: refuse a garment that is inside the body once placed.

    Returns:
        The template and what was decided (``units``, ``up``, ``kind`` with whether each
        was guessed, the placement, the attachment, the UVs' source).

    Raises:
        LoosefitInputError: see :func:`~loosefit.garment.importer.read_garment_mesh`,
            :func:`~loosefit.garment.importer.detect_units` and :func:`check_clear_of_body`.
    """
    from pathlib import Path

    from loosefit.garment.importer import (
        KINDS,
        UNITS,
        UP_AXES,
        detect_kind,
        detect_units,
        detect_up,
        read_garment_mesh,
        to_z_up,
    )
    from loosefit.garment.obj import garment_uvs

    path = Path(path)
    mesh = read_garment_mesh(path)
    report = {
        "source": str(path),
        "vertices": len(mesh.vertices),
        "faces": len(mesh.faces),
        "dropped_vertices": mesh.dropped_vertices,
    }
    if up is not None and up not in UP_AXES:
        raise LoosefitInputError("--up", "up", f"one of {UP_AXES}", repr(up))
    if units is not None and units not in UNITS:
        raise LoosefitInputError("--units", "units", f"one of {list(UNITS)}", repr(units))
    if kind is not None and kind not in KINDS:
        raise LoosefitInputError("--kind", "kind", f"one of {KINDS}", repr(kind))
    report["up"] = {
        "value": up or detect_up(mesh.vertices, mesh.faces, path),
        "guessed": up is None,
    }
    v = to_z_up(mesh.vertices, report["up"]["value"])
    if units is None:
        units, sizes = detect_units(v, path)
        report["units"] = {
            "value": units,
            "guessed": True,
            "height_m": sizes[units][0],
            "width_m": sizes[units][1],
        }
    else:
        report["units"] = {"value": units, "guessed": False}
    v = v * UNITS[units]
    report["kind"] = {"value": kind or detect_kind(mesh.faces), "guessed": kind is None}
    kind = report["kind"]["value"]
    v, report["placement"] = place_garment(v, mesh.faces, avatar, kind, offset)
    if any(offset):
        report["placement"]["offset_m"] = [float(t) for t in offset]  # the --offset given
    waist, how = attachment_of(v, mesh.faces, kind, attach)
    report["attachment"] = {"vertices": len(waist), "as": how}
    uvs, face_uvs, uv_source = garment_uvs(v, mesh.faces, mesh.uvs, mesh.face_uvs)
    report["uv_source"] = uv_source
    meta = {"kind": kind, "attachment": how, "import": report}
    template = GarmentTemplate(
        v.astype(np.float32), mesh.faces, uvs, face_uvs, waist, name=name or path.stem, meta=meta
    )
    if check:
        check_clear_of_body(template, avatar, path)
    return template, report


def check_fitted_shape(template: GarmentTemplate, avatar: Avatar, source="garment") -> None:
    """Raise if ``template`` was fitted to another body than ``avatar`` (its ``meta["fit"]``)."""
    fitted = (template.meta or {}).get("fit", {}).get("shape")
    if not fitted:
        return
    mine = {k: float(v) for k, v in avatar.shape.items()}
    if any(abs(float(v) - mine.get(k, np.nan)) > 1e-6 for k, v in fitted.items()):
        given = ",".join(f"{k}={float(v):g}" for k, v in fitted.items())
        raise LoosefitInputError(
            source,
            "fit.shape",
            f"the avatar it was fitted to ({given})",
            ",".join(f"{k}={v:g}" for k, v in mine.items()),
            hint=f"simulate with --shape {given}",
        )
