"""A garment made for another body, fitted to the avatar (``loosefit garment FILE --fit``).

:func:`~loosefit.fitting.place.import_garment` refuses a garment whose vertices are inside the
avatar's rest body. :func:`fit_garment` takes it anyway, in three steps:

1. it is placed as any garment file is (units, axes, the placement rules of
   :mod:`loosefit.fitting.place`), then every vertex is pushed out of the rest body by the
   project's collision handling, which keeps the mesh's Laplacian (paper Eq. 16,
   :class:`~loosefit.inference.stages.collision.CollisionHandler`): a dent, not a spike;
2. it drapes on the avatar standing still in the simulator (the settle phase every
   clip starts with, :func:`~loosefit.sim.driver.settle`), so its top sits on the body;
3. the largest and mean displacement (the placed input to the fitted garment) and what is
   left inside the body are reported (:class:`FitReport`).

With ``shape="auto"`` the avatar's phenotype is chosen first (:func:`best_shape`): the
anny body the garment was most likely made for, the one it fits with the fewest vertices
inside and its top closest to the skin. The fitted template remembers that shape
(``meta["fit"]["shape"]``); a data set must be simulated on it (``--shape``), and the
data set carries it on into training, the model and ``animate`` (its manifest's
``body.shape``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace

import numpy as np
import torch

from loosefit.body.avatar import DEFAULT_SHAPE, Avatar, AvatarConfig
from loosefit.errors import LoosefitInputError
from loosefit.fitting.place import FIT_REACH
from loosefit.types import GarmentTemplate

SHAPE_SEARCH = ("weight", "height", "proportions")  # the phenotypes --shape auto tries

# The stages of a fit, in order, as ``progress(stage, done, total)`` names them, and what
# each counts (total 0: not known beforehand). The search runs with ``shape="auto"`` only,
# the drape with ``settle_seconds > 0``; the push runs again after a drape that left cloth
# inside the body.
SEARCH, PLACE, PUSH, DRAPE, CHECK = (
    "search the body it fits",
    "place on the avatar",
    "push out of the body (Eq. 16)",
    "drape on the avatar standing still",
    "check what is left inside",
)
STAGE_UNITS = {SEARCH: "shape", PLACE: "step", PUSH: "step", DRAPE: "frame", CHECK: "step"}

Progress = Callable[[str, int, int], None]  # progress(stage, done, total)


def _stage(progress: Progress | None, stage: str, done: int, total: int = 1) -> None:
    if progress is not None:
        progress(stage, done, total)


def _counter(progress: Progress | None, stage: str) -> Callable[[int, int], None] | None:
    """``progress`` as the ``progress(done, total)`` of one stage's loop."""
    if progress is None:
        return None
    return lambda done, total: progress(stage, done, total)


@dataclass
class FitConfig:
    """How a garment made for another body is fitted.

    Why the defaults hold the values they do: docs/design/notes/fit_config.md.
    """

    clearance: float = 0.004  # m, pushed vertices end this far outside the body
    rings: int = 8  # Eq. 16: a push moves the cloth within this many edges of a vertex
    reach: float = FIT_REACH  # m, the deepest a vertex may be inside the body and be pushed out
    attach_reach: float = 0.1  # m, the farthest the garment's top may be from the body
    tolerance: float = 0.005  # m, after the push no vertex may be deeper inside than this
    settle_seconds: float = 0.5  # s of drape on the avatar standing still; 0: none
    cloth: object | None = None  # the drape's ClothConfig (None: the defaults, see the note)
    fps: float = 30.0  # the drape steps whole frames at this rate

    def __post_init__(self) -> None:
        for name in ("clearance", "reach", "attach_reach", "tolerance", "fps"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
                raise LoosefitInputError("FitConfig", name, "a positive number", repr(value))
        if not (isinstance(self.rings, int) and self.rings >= 1):
            raise LoosefitInputError("FitConfig", "rings", "an integer >= 1", repr(self.rings))
        if not (np.isfinite(self.settle_seconds) and self.settle_seconds >= 0):
            raise LoosefitInputError(
                "FitConfig", "settle_seconds", "a number >= 0", repr(self.settle_seconds)
            )


@dataclass
class FitReport:
    """What fitting did (metres; displacements from the garment as placed).

    Attributes:
        inside_before, depth_before: vertices inside the rest body as placed, the deepest.
        pushed_max, pushed_mean: displacement by the push (Eq. 16) alone.
        moved_max, moved_mean: displacement placed -> fitted (push and drape).
        inside_after, depth_after: vertices inside the rest body once fitted, the deepest.
        shape: the avatar's phenotype it was fitted to (anny's names).
        shape_tried: phenotypes :func:`best_shape` tried (0: the shape was given).
        seconds: wall-clock time of the fit (the search and the drape included).
    """

    inside_before: int
    depth_before: float
    pushed_max: float
    pushed_mean: float
    moved_max: float
    moved_mean: float
    inside_after: int
    depth_after: float
    shape: dict = field(default_factory=dict)
    shape_tried: int = 0
    seconds: float = 0.0

    def format(self) -> str:
        """Two lines for the command's log."""
        return (
            f"{self.inside_before} vertices inside the body as placed (deepest "
            f"{100 * self.depth_before:.1f} cm); pushed out (Eq. 16) by at most "
            f"{100 * self.pushed_max:.1f} cm, mean {1000 * self.pushed_mean:.1f} mm; draped: "
            f"moved by at most {100 * self.moved_max:.1f} cm, mean {1000 * self.moved_mean:.1f}"
            f" mm\n{self.inside_after} vertices inside once fitted (deepest "
            f"{1000 * self.depth_after:.1f} mm), in {self.seconds:.1f} s"
        )


@dataclass
class FitResult:
    """A garment file fitted to a body (:func:`fit_garment`).

    Attributes:
        template: the fitted garment on the avatar's rest pose (V vertices; its
            ``meta["fit"]`` holds the report).
        report: what fitting did (:class:`FitReport`).
        avatar: the body it was fitted to: simulate it on this one.
    """

    template: GarmentTemplate
    report: FitReport
    avatar: Avatar


def inside_of(template_vertices: np.ndarray, avatar: Avatar, arms) -> tuple[int, float, np.ndarray]:
    """Vertices (V, 3) inside the avatar's rest collider: their count, the deepest (m),
    and the (V,) distances to the body."""
    from loosefit.geometry.query import closest_points

    body = avatar.rest_vertices.double().cpu().numpy()
    faces = avatar.collider_faces(arms=arms).cpu().numpy()
    hit = closest_points(body, faces, np.asarray(template_vertices, np.float64))
    depth = float(hit.distance[hit.inside].max()) if hit.inside.any() else 0.0
    return int(hit.inside.sum()), depth, np.asarray(hit.distance, np.float64)


def push_out(template: GarmentTemplate, avatar: Avatar, config: FitConfig) -> np.ndarray:
    """(V, 3) the template's vertices pushed out of the avatar's rest body, ``clearance``
    outside it, keeping the mesh's Laplacian (Eq. 16)."""
    from loosefit.fitting.place import collider_arms
    from loosefit.geometry.query import Surface
    from loosefit.inference.stages.collision import CollisionConfig, CollisionHandler

    faces = avatar.collider_faces(arms=collider_arms(template)).cpu().numpy()
    body = Surface(avatar.rest_vertices.float().cpu().numpy(), faces, winding_number=True)
    collide = CollisionConfig(
        epsilon=config.clearance,
        rings=config.rings,
        reach=config.reach,
        finish_reach=config.reach,
        iterations=8,
    )
    handler = CollisionHandler(template.faces, template.num_vertices, collide, template.vertices)
    out = handler.resolve(torch.from_numpy(template.vertices.astype(np.float32)), body)
    return out.vertices.double().numpy()


def fit_template(
    template: GarmentTemplate,
    avatar: Avatar,
    config: FitConfig | None = None,
    source="garment",
    progress: Progress | None = None,
) -> tuple[GarmentTemplate, FitReport]:
    """A garment placed on the avatar's rest pose (perhaps partly inside the body) pushed
    out of it and draped there.

    Args:
        template: the garment as placed
            (:func:`~loosefit.fitting.place.import_garment`, unchecked).
        avatar: the body.
        config: the push and the drape.
        source: what errors name (the file).
        progress: called as ``progress(stage, done, total)`` as each stage starts and as
            it goes (:data:`STAGE_UNITS`: the push, every frame of the drape, the check).

    Returns:
        The fitted template (its ``meta["fit"]``: the report) and the :class:`FitReport`.
        Its vertices are the draped garment, where a simulation starts; its
        ``rest_vertices`` are the garment as placed, so that the cloth keeps the file's
        rest lengths (the push and the drape stretch it; they do not remake it).

    Raises:
        LoosefitInputError: its attached vertices farther than ``reach`` from the body (a
            garment far from it), or vertices still deeper than ``tolerance`` inside it
            after the push.
    """
    from loosefit.fitting.place import collider_arms

    config = config or FitConfig()
    start = time.perf_counter()
    _stage(progress, PUSH, 0)
    arms = collider_arms(template)
    v0 = template.vertices.astype(np.float64)
    inside_before, depth_before, dist = inside_of(v0, avatar, arms)
    far = float(dist[template.waist].max())
    if far > config.attach_reach:
        raise LoosefitInputError(
            source,
            "placement",
            f"a garment whose attached vertices (its top) lie within "
            f"{100 * config.attach_reach:.0f} cm of the body",
            f"they are up to {100 * far:.1f} cm from it",
            hint="--fit dresses a body with a garment made for another, not one "
            "far from it: check --units and --kind, or move it with --offset X,Y,Z (metres)",
        )
    pushed = push_out(template, avatar, config)
    left, deepest, _ = inside_of(pushed, avatar, arms)
    if deepest > config.tolerance:
        raise LoosefitInputError(
            source,
            "placement",
            f"a garment that can be pushed off the body (no vertex more "
            f"than {1000 * config.tolerance:.0f} mm inside it after the push)",
            f"{left} vertices still inside, the deepest {1000 * deepest:.1f} mm",
            hint="a garment round the body, or deeper in it than "
            f"{100 * config.reach:.0f} cm, cannot be fitted: check --units and --kind",
        )
    _stage(progress, PUSH, 1)
    fitted = pushed
    if config.settle_seconds > 0:
        from loosefit.sim.cloth_config import ClothConfig
        from loosefit.sim.driver import settle

        cloth = config.cloth or ClothConfig(arm_collision=arms)
        cloth = replace(cloth, settle_seconds=config.settle_seconds)
        draped = GarmentTemplate(
            pushed.astype(np.float32),
            template.faces,
            template.uvs,
            template.face_uvs,
            template.waist,
            name=template.name,
            meta=dict(template.meta),
            rest_vertices=template.rest,
        )
        frames = int(round(cloth.settle_seconds * config.fps))  # as settle steps them
        _stage(progress, DRAPE, 0, frames)
        fitted = settle(avatar, draped, cloth, config.fps, _counter(progress, DRAPE))
        fitted = fitted.astype(np.float64)
        if inside_of(fitted, avatar, arms)[1] > 0:  # the drape's contact left some: out again
            _stage(progress, PUSH, 0)
            draped.vertices = fitted.astype(np.float32)
            fitted = push_out(draped, avatar, config)
            _stage(progress, PUSH, 1)
    _stage(progress, CHECK, 0)
    inside_after, depth_after, _ = inside_of(fitted, avatar, arms)
    _stage(progress, CHECK, 1)
    push_d = np.linalg.norm(pushed - v0, axis=1)
    moved = np.linalg.norm(fitted - v0, axis=1)
    report = FitReport(
        inside_before,
        depth_before,
        float(push_d.max()),
        float(push_d.mean()),
        float(moved.max()),
        float(moved.mean()),
        inside_after,
        depth_after,
        shape=dict(avatar.shape),
        seconds=time.perf_counter() - start,
    )
    meta = {**template.meta, "fit": asdict(report)}
    out = GarmentTemplate(
        fitted.astype(np.float32),
        template.faces,
        template.uvs,
        template.face_uvs,
        template.waist,
        name=template.name,
        meta=meta,
        rest_vertices=template.rest,
    )
    return out, report


SHAPE_EASE = 0.025  # m, how far a garment's top stands off the body it was made for, on
#   average: 2.6 cm for the parametric strapless dress. Without it (the closer the better)
#   the search took that dress, made for weight 0.8, height 0.9, to weight 1, height 1


def shape_cost(template: GarmentTemplate, avatar: Avatar, ease: float = SHAPE_EASE) -> float:
    """How badly a placed garment fits a body (m): the depth of its vertices inside it,
    summed, plus how far its attached vertices (its top) are from ``ease`` off the skin,
    on average."""
    from loosefit.fitting.place import collider_arms
    from loosefit.geometry.query import closest_points

    body = avatar.rest_vertices.double().cpu().numpy()
    faces = avatar.collider_faces(arms=collider_arms(template)).cpu().numpy()
    hit = closest_points(body, faces, template.vertices.astype(np.float64))
    depth = np.where(hit.inside, hit.distance, 0.0)
    return float(depth.sum() + abs(hit.distance[template.waist].mean() - ease))


def best_shape(
    place,
    start: dict | None = None,
    step: float = 0.2,
    rounds: int = 2,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[dict, Avatar, int]:
    """The anny phenotype a garment fits best (:func:`shape_cost`), by coordinate descent
    over :data:`SHAPE_SEARCH` from ``start`` (default: the project's avatar), each value in
    [0, 1], the step halved each round.

    Args:
        place: ``place(avatar) -> GarmentTemplate``, the garment placed on a body.
        start: the phenotype to start from.
        step: the first round's step.
        rounds: rounds of the descent.
        progress: called as ``progress(tried, 0)`` after each shape tried (0: the number
            of shapes to try is not known beforehand).

    Returns:
        The shape, its avatar, and how many shapes were tried.
    """
    shape = {**DEFAULT_SHAPE, **(start or {})}
    seen: dict = {}

    def cost(s: dict) -> float:
        key = tuple(round(s[k], 4) for k in SHAPE_SEARCH)
        if key not in seen:
            avatar = Avatar(AvatarConfig(shape=dict(s)))
            seen[key] = (shape_cost(place(avatar), avatar), avatar)
            if progress is not None:
                progress(len(seen), 0)
        return seen[key][0]

    best = cost(shape)
    for _ in range(rounds):
        for name in SHAPE_SEARCH:
            for sign in (1.0, -1.0):
                while True:
                    value = round(float(np.clip(shape[name] + sign * step, 0.0, 1.0)), 4)
                    trial = {**shape, name: value}
                    if trial[name] == shape[name] or cost(trial) >= best:
                        break
                    shape, best = trial, cost(trial)
        step /= 2
    key = tuple(round(shape[k], 4) for k in SHAPE_SEARCH)
    return shape, seen[key][1], len(seen)


def fit_garment(
    path,
    shape: dict | str | None = None,
    config: FitConfig | None = None,
    units: str | None = None,
    up: str | None = None,
    kind: str | None = None,
    *,
    offset=(0.0, 0.0, 0.0),
    attach="auto",
    avatar: Avatar | None = None,
    progress: Progress | None = None,
) -> FitResult:
    """A garment file made for another body, fitted to the avatar's rest pose.

    Args:
        path: ``.obj``, ``.gltf`` or ``.glb``
            (see :func:`~loosefit.fitting.place.import_garment`).
        shape: the avatar's phenotype (anny's names; None: the project's avatar), or
            ``"auto"``: the one the garment fits best (:func:`best_shape`).
        config: the push and the drape.
        units, up, kind, offset, attach: as for :func:`~loosefit.fitting.place.import_garment`.
        avatar: the body, already built (then ``shape`` must be None).
        progress: called as ``progress(stage, done, total)`` as each of the fit's stages
            (:data:`STAGE_UNITS`) starts and as it goes.

    Returns:
        A :class:`FitResult`: the fitted template, the :class:`FitReport`, and the avatar
        (simulate on it).

    Raises:
        LoosefitInputError: an unreadable file or bad option (as the import), a closed
            surface (no opening to hang it by), a garment far from the body or one that
            cannot be pushed off it (:func:`fit_template`).
    """
    from pathlib import Path

    from loosefit.fitting.place import import_garment
    from loosefit.garment.importer import read_garment_mesh
    from loosefit.garment.mesh_checks import boundary_loops

    start = time.perf_counter()
    path = Path(path)
    if not boundary_loops(read_garment_mesh(path).faces):
        raise LoosefitInputError(
            path,
            "openings",
            "cloth with openings (a waistband, a neckline, a hem)",
            "a closed surface",
            hint="--fit pushes a garment off the body and hangs it by its "
            "top opening: a closed surface round the body has none",
        )

    def place(body: Avatar) -> GarmentTemplate:
        return import_garment(path, body, units, up, kind, offset, attach=attach, check=False)[0]

    tried = 0
    if shape == "auto":
        _stage(progress, SEARCH, 0, 0)
        found, avatar, tried = best_shape(place, progress=_counter(progress, SEARCH))
    elif avatar is None:
        avatar = Avatar(AvatarConfig(shape=dict(shape or {})))
    _stage(progress, PLACE, 0)
    placed = place(avatar)
    _stage(progress, PLACE, 1)
    template, report = fit_template(placed, avatar, config, path, progress)
    report.shape_tried, report.seconds = tried, time.perf_counter() - start
    template.meta["fit"] = asdict(report)
    return FitResult(template=template, report=report, avatar=avatar)
