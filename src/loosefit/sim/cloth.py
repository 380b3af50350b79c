"""Ground-truth cloth: a garment simulated on the avatar as it moves, with Newton's VBD solver.

The garment is a Newton cloth mesh (Vertex Block Descent, He Chen et al. 2024)
and the body a collision mesh that deforms with the motion:

* **Body.** One static mesh shape holds the full-resolution, watertight anny
  body. Before every substep its ``wp.Mesh`` points are overwritten with the
  body posed for the *end* of that substep (linear interpolation between the
  frame's start and end vertices), its velocities with the frame's vertex
  velocities (for friction), and its BVH is refitted. Newton's soft contacts
  test inside/outside against a watertight mesh by ray parity, so a cloth
  vertex that ends up inside the body is pushed back out (up to
  ``body_contact_gap + body_contact_distance`` deep; deeper ones get no contact).
* **Waistband.** Its vertices are not simulated: each is glued to a point of
  the body (a face, barycentric coordinates and an offset in the face's frame,
  found once, at the start) and moved there before every substep. By default
  the band is first pulled onto the body, ``waist_offset`` outside it and
  respaced along its length (:func:`glue_waist`).
* **Timeline.** The garment first drapes under gravity on the rest pose
  (``settle_seconds``), then the body blends from the rest pose into the
  motion's first frame (``blend_seconds``: slerp of local rotations, lerp of
  the root); recording starts at the motion's first frame, so frame ``t`` of
  the result is motion frame ``t``.

The simulator follows Newton's pattern: a static ``Model``, two ``State``\\ s
swapped after every ``solver.step``. Warp's CPU kernels run on one thread;
the first run compiles them (about 35 s, cached under ``~/.cache/warp``).
"""

from __future__ import annotations

import hashlib
import math
import time
import zipfile
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import torch
import warp as wp

from loosefit.atomic import atomic_path
from loosefit.body.chain import preroll
from loosefit.errors import LoosefitInputError
from loosefit.eval.quality import quality
from loosefit.geometry.query import closest_points
from loosefit.types import GarmentTemplate, Motion

if TYPE_CHECKING:
    from loosefit.body.avatar import Avatar
    from loosefit.eval.body_regions import BodyParts


class SimulationError(RuntimeError):
    """The simulation diverged (NaN, or a vertex flew away); nothing is returned."""


@dataclass
class ClothConfig:
    """How the garment is simulated. Units: metres, kilograms, seconds."""

    # time stepping
    substeps: int = 20  # solver steps per motion frame (dt = 1/600 s at 30 fps)
    # A frame in which the waistband moves more than ``substep_waist_move`` per substep gets
    # more substeps, up to ``max_substeps`` (see substep_schedule). With self-contact a cloth
    # vertex moves at most 0.85 (self_contact_margin + self_contact_gap) per substep, 12.75 mm
    # with the defaults; the hem swings about three times as far from the hips as the
    # waistband, so 4 mm of waistband per substep keeps a spinning hem under that cap. At a
    # fixed 20 substeps a 26 rad/s salsa spin (8.4 mm per substep) tangled and exploded the
    # skirt; at 40 it held (max strain 0.32). Costs ~5% more on the salsa clips.
    max_substeps: int = 60
    substep_waist_move: float = 0.004  # m
    iterations: int = 5  # VBD iterations per substep
    # fabric
    density: float = 0.15  # kg/m^2: 150 g/m^2, a light woven skirt fabric (cotton lawn, poplin)
    stretch_ke: float = 1.0e3  # N/m, membrane shear stiffness (Newton's tri_ke, Lame mu)
    stretch_ka: float = 1.0e3  # N/m, membrane area stiffness (Newton's tri_ka, Lame lambda)
    stretch_kd: float = 1.0e-2  # s, membrane strain-rate damping (Newton's tri_kd)
    bend_ke: float = 1.0e-2  # N m/rad per metre of edge, dihedral bending stiffness (edge_ke)
    bend_kd: float = 1.0e-3  # bending damping (Newton's edge_kd)
    flat_rest: bool = True  # bending rest angle 0 (flat fabric), not the template's draped shape
    # colour the mesh so that no bending edge joins two vertices of a colour: 7 colours
    # instead of 3-4 and ~1.4x slower; bending is weak, so solving it Jacobi-style is harmless
    color_bending: bool = False
    # forces on the cloth
    gravity: float = -9.81  # m/s^2 along +Z
    air_damping: float = 0.3  # 1/s, velocities decay as exp(-air_damping t): a stand-in for drag
    settle_damping: float = 5.0  # 1/s, the same while settling, so the drape comes to rest
    # contact with the body
    body_contact_distance: float = 0.004  # m, cloth vertices are kept this far outside the body
    # m, extra reach of body-contact detection; a vertex deeper than gap + distance inside the
    # body gets no contact at all. 2 cm lost cloth that a fast crouch folded 2.4-3 cm deep
    # (salsa 60_02 played 1.5x as fast: a vertex 3.1 cm inside, 2.7 cm with 4 cm of reach;
    # docs/PENETRATION.md)
    body_contact_gap: float = 0.04
    contact_ke: float = 1.0e4  # N/m, contact stiffness (cloth-body and cloth-cloth)
    contact_kd: float = 1.0e-2  # N s/m, contact damping (cloth-body and cloth-cloth)
    body_friction: float = 0.3  # Coulomb friction between cloth and body
    # The arms (from the shoulder down) collide with the cloth. Off by default: a forearm
    # or hand resting on the hip pinches the cloth against the torso, and contact against
    # one body mesh (an inside/outside test) cannot free cloth caught between two of its
    # parts: it stretched salsa skirts by 7x. Without the arms the collider is the body
    # with its shoulders capped; a hand passing the skirt goes through it. "upper": the
    # upper arms collide, the arms from the elbows down do not (a dress's bodice).
    arm_collision: bool | str = False
    # The arms that arm_collision cuts from the body (all of them, or from the elbows for
    # "upper") as a collider of their own, closed at the cut, with this Coulomb friction
    # (0: frictionless); None: they do not collide (data sets made before 2026-11-26).
    # A mesh of their own has its own inside/outside test, so cloth between a forearm and
    # the hip is not caught in one mesh's overlap, and without friction a hand pushes the
    # cloth without dragging it down (salsa 60_01, frames 0-90: no frame with cloth deeper
    # than 5 mm inside the body against 54, edge strain as without arms; docs/DATASET.md).
    # Nothing is cut with arm_collision true, and this does not apply.
    arm_friction: float | None = 0.0
    # m: after each frame of the motion, a cloth vertex deeper than this inside the body
    # (against each mesh the cloth collides with) is put back on the skin of the part it is
    # in, where it went in, moving with it (TrappedRelease): cloth pinched between two body
    # parts (the thighs crossing in a turning leap, ballet 05_16) can sink past the
    # contact's reach and stay inside for the rest of the clip (81 of 122 frames, 6.4 cm
    # deep; four times the reach did not free it). None: never.
    # Measured there (docs/DATASET.md), it tears the cloth wherever it puts the vertices
    # (strain p99 0.26 -> 13-30: to the closest skin, or back where they went in,
    # TrappedRelease): off by default.
    release_depth: float | None = None
    # A pose that folds into itself (a thigh centimetres into the belly in a deep crouch)
    # makes a lens that ray parity calls outside, and cloth folded into it stays inside the
    # body; the collider's limbs are pressed out of the rest of the body as flesh would be
    # (loosefit.sim.overlap; the posed body and every measure are unchanged). Data sets
    # made before this field existed were made without it.
    flatten_overlaps: bool = True
    # m: a pressed limb vertex stops this far inside the rest of the body (negative: this
    # far outside it, room left for the cloth between the two)
    overlap_inset: float = 0.002
    self_friction: float = 0.2  # Coulomb friction between two layers of cloth
    # contact of the cloth with itself (costs ~3x; without it ~10% of triangles cross in a spin)
    self_contact: bool = True  # resolve cloth-cloth contact
    self_contact_margin: float = 0.005  # m, distance kept between two layers of cloth
    # m, extra reach of self-contact detection. With self-contact a vertex moves at most
    # 0.85 (margin + gap) per substep (Newton's DAT truncation), so this caps cloth speed:
    # 7.6 m/s with the defaults; 4 mm in all froze a spinning skirt into a twist
    self_contact_gap: float = 0.01
    # m, cloth points closer than this in the rest shape never collide: ~20% faster at 5 cm,
    # but tight folds then cross (1% of triangles in a spin instead of 0.05%)
    self_contact_rest_exclusion: float = 0.0
    # timeline
    settle_seconds: float = 1.0  # drape under gravity on the rest pose before anything moves
    blend_seconds: float = 0.5  # the body blends from the rest pose into the motion's first frame
    # settle where the motion starts (the root's floor position and heading) rather than at
    # the origin facing -Y, so the blend never drags the skirt across the room
    settle_at_start: bool = True
    # attachment and safety
    # m, the waistband is held this far outside the body along its normal (snugger than the
    # template's band, 1-2.5 cm out, so it gathers ~10%); None holds it exactly as placed
    waist_offset: float | None = 0.003
    jitter: float = 1.0e-4  # m, seeded random offset of the initial vertices: breaks symmetry
    max_distance: float = 10.0  # m, a vertex this far from the body's box stops the run
    # execution
    capture: bool = True  # replay recorded warp graphs for the substeps (~20% faster on CPU)
    device: str = "cpu"  # warp device, "cpu" or "cuda:0"
    seed: int = 0  # seeds the jitter; results are identical for a given seed and device

    def __post_init__(self) -> None:
        src = "ClothConfig"
        for name in ("substeps", "iterations", "max_substeps"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 1):
                raise LoosefitInputError(src, name, "an integer >= 1", repr(value))
        if not isinstance(self.flatten_overlaps, bool):
            raise LoosefitInputError(src, "flatten_overlaps", "true or false",
                                     repr(self.flatten_overlaps))  # fmt: skip
        if self.arm_collision not in (False, True, "upper"):
            raise LoosefitInputError(src, "arm_collision", "false, true or 'upper'",
                                     repr(self.arm_collision))  # fmt: skip
        if self.max_substeps < self.substeps:
            raise LoosefitInputError(
                src, "max_substeps", f">= substeps ({self.substeps})", repr(self.max_substeps)
            )
        positive = (
            "density",
            "stretch_ke",
            "substep_waist_move",
            "body_contact_distance",
            "contact_ke",
            "max_distance",
        )
        nonnegative = (
            "stretch_ka", "stretch_kd", "bend_ke", "bend_kd", "air_damping", "settle_damping",
            "jitter", "body_contact_gap", "contact_kd", "body_friction", "self_friction",
            "self_contact_margin", "self_contact_gap", "self_contact_rest_exclusion",
            "settle_seconds", "blend_seconds",
        )  # fmt: skip
        # None turns these off; a number is checked as the others
        optional_positive = ("release_depth",)
        optional_nonnegative = ("waist_offset", "arm_friction")
        optional = optional_positive + optional_nonnegative
        positive += tuple(n for n in optional_positive if getattr(self, n) is not None)
        nonnegative += tuple(n for n in optional_nonnegative if getattr(self, n) is not None)
        for name in positive + nonnegative:
            value = getattr(self, name)
            ok = isinstance(value, int | float) and not isinstance(value, bool)
            low_ok = ok and (value > 0 if name in positive else value >= 0)
            if not (low_ok and math.isfinite(value)):
                want = "a finite number > 0" if name in positive else "a finite number >= 0"
                raise LoosefitInputError(src, name, ("None or " if name in optional else "")
                                         + want, repr(value))  # fmt: skip
        if self.self_contact and self.self_contact_margin + self.self_contact_gap <= 0:
            raise LoosefitInputError(
                src, "self_contact_margin + self_contact_gap", "> 0 with self_contact on", "0"
            )
        if self.body_friction > 0 and self.self_friction <= 0:
            # Newton mixes friction as sqrt(mu_cloth * mu_shape); see ClothSimulator.
            raise LoosefitInputError(
                src, "self_friction", "> 0 when body_friction > 0", repr(self.self_friction)
            )

    @property
    def colliding_arms(self) -> bool | str:
        """What of the arms the cloth meets, in ``arm_collision``'s terms: True when they
        collide in the body's mesh or as a mesh of their own (``arm_friction``), else
        ``arm_collision``. The pressing of overlapping limbs and the pose correction treat
        these as limbs."""
        return True if self.arm_friction is not None else self.arm_collision

    @classmethod
    def tiny(cls, **overrides) -> ClothConfig:
        """A fast configuration for tests: 8 substeps, 0.3 s of settling, a short blend."""
        kwargs = dict(
            substeps=8, max_substeps=8, iterations=4, settle_seconds=0.3, blend_seconds=0.2
        )
        kwargs.update(overrides)
        return cls(**kwargs)


@dataclass
class SimResult:
    """A simulated garment sequence.

    Attributes:
        garment_vertices: (T, V, 3) float32 world positions, one per motion frame.
        faces: (F, 3) int64 garment triangles (the template's).
        fps: frames per second (the motion's).
        seconds_per_frame: wall-clock seconds per simulated frame, settle and blend included.
        preroll_frames: frames simulated before the motion's first frame (settle + blend).
        settled_vertices: (V, 3) float32 garment at the end of the settle phase.
        quality: :func:`quality` of the recorded frames.
        stats: sizes and timings (numbers), for reports.
    """

    garment_vertices: np.ndarray
    faces: np.ndarray
    fps: float
    seconds_per_frame: float
    preroll_frames: int
    settled_vertices: np.ndarray
    quality: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)


# -- warp kernels ---------------------------------------------------------------


@wp.kernel
def _pose_body_kernel(
    start: wp.array(dtype=wp.vec3),
    end: wp.array(dtype=wp.vec3),
    alpha: float,
    inv_frame_dt: float,
    points: wp.array(dtype=wp.vec3),
    velocities: wp.array(dtype=wp.vec3),
):
    """Body vertices a fraction ``alpha`` into the frame, and their (constant) velocities."""
    i = wp.tid()
    a = start[i]
    d = end[i] - a
    points[i] = a + alpha * d
    velocities[i] = d * inv_frame_dt


@wp.func
def _face_frame(x0: wp.vec3, x1: wp.vec3, x2: wp.vec3, outward: float):
    """A face's orthonormal frame: first edge, in-plane normal to it, outward normal."""
    t1 = wp.normalize(x1 - x0)
    n = outward * wp.normalize(wp.cross(x1 - x0, x2 - x0))
    return t1, wp.cross(n, t1), n


@wp.kernel
def _pin_waist_kernel(
    points: wp.array(dtype=wp.vec3),
    body_faces: wp.array(dtype=wp.vec3i),
    glue_faces: wp.array(dtype=wp.int32),
    glue_bary: wp.array(dtype=wp.vec3),
    glue_local: wp.array(dtype=wp.vec3),
    outward: float,
    waist_particles: wp.array(dtype=wp.int32),
    q0: wp.array(dtype=wp.vec3),
    q1: wp.array(dtype=wp.vec3),
):
    """Move each waistband particle to its glued point (see :class:`WaistGlue`)."""
    i = wp.tid()
    f = body_faces[glue_faces[i]]
    x0 = points[f[0]]
    x1 = points[f[1]]
    x2 = points[f[2]]
    t1, t2, n = _face_frame(x0, x1, x2, outward)
    b = glue_bary[i]
    o = glue_local[i]
    p = b[0] * x0 + b[1] * x1 + b[2] * x2 + o[0] * t1 + o[1] * t2 + o[2] * n
    q0[waist_particles[i]] = p
    q1[waist_particles[i]] = p


@wp.kernel
def _damp_kernel(factor: wp.array(dtype=float), qd: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    qd[i] = qd[i] * factor[0]


# -- the simulator ----------------------------------------------------------------


def _signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Volume enclosed by a closed mesh: positive when its faces wind counter-clockwise outside."""
    a, b, c = (vertices[faces[:, i]].astype(np.float64) for i in range(3))
    return float(np.einsum("ij,ij->", a, np.cross(b, c)) / 6.0)


@dataclass
class WaistGlue:
    """Where each waistband vertex is held on the body.

    The point is ``sum(barycentric * face corners) + local @ (t1, t2, n)`` with
    ``(t1, t2, n)`` the face's frame (first edge, in-plane perpendicular, outward
    normal), so it follows the skin as the body moves and bends.

    Attributes:
        faces: (W,) body face of each waistband vertex (its closest at the start).
        barycentric: (W, 3) weights of the closest point on that face.
        local: (W, 3) offset from the closest point in the face's frame.
        outward: +1 if the body's faces wind counter-clockwise seen from outside, else -1.
    """

    faces: np.ndarray
    barycentric: np.ndarray
    local: np.ndarray
    outward: float


def _resample_like(curve: np.ndarray, like: np.ndarray) -> np.ndarray:
    """Points on the closed polyline ``curve`` (N, 3) at the arc-length fractions of ``like``."""

    def fractions(c: np.ndarray) -> tuple[np.ndarray, float]:
        seg = np.linalg.norm(np.roll(c, -1, 0) - c, axis=-1)  # segment i: c[i] -> c[i + 1]
        return np.concatenate([[0.0], np.cumsum(seg)]) / seg.sum(), seg.sum()

    s_curve, _ = fractions(curve)
    s_like, _ = fractions(like)
    closed = np.concatenate([curve, curve[:1]])  # (N + 1, 3)
    return np.stack([np.interp(s_like[:-1], s_curve, closed[:, k]) for k in range(3)], -1)


def glue_waist(
    waist_points: np.ndarray,
    body_vertices: np.ndarray,
    body_faces: np.ndarray,
    offset: float | None,
    loop: bool = True,
) -> WaistGlue:
    """Glue a waistband (a closed loop of points, in order) to the body surface.

    With ``offset`` None each point keeps its offset from its closest body point,
    in that face's frame: the band is held exactly as placed. With an ``offset``,
    the band is pulled onto the body: the loop is projected onto the surface,
    respaced along its length as the original points were (projection bunches
    points where the body is flatter than the band), and each point is held
    ``offset`` outside its closest surface point along the normal.

    Args:
        waist_points: (W, 3) waistband vertices placed on the body, in loop order.
        body_vertices: (Vb, 3) the body as the waistband is placed on it.
        body_faces: (Fb, 3) triangles of the closed body mesh.
        offset: metres outside the surface; None keeps each point's own offset.
        loop: the points are a closed band in order (respaced along it); False: separate
            points (a dress's straps), each projected alone.

    Returns:
        The :class:`WaistGlue`; :func:`glued_points` evaluates it on a posed body.
    """
    placed = np.asarray(waist_points, np.float64)
    points = placed
    if offset is not None and loop and len(points) >= 3:
        for _ in range(4):  # projecting moves the respaced points a little: repeat
            surface = closest_points(body_vertices, body_faces, points).points.astype(np.float64)
            points = _resample_like(surface, placed)
    hit = closest_points(body_vertices, body_faces, points)
    outward = 1.0 if _signed_volume(body_vertices, body_faces) > 0 else -1.0
    t1, t2, n = _face_frames(body_vertices, body_faces[hit.faces], outward)  # (W, 3) each
    delta = points - hit.points
    local = np.stack([(delta * t).sum(-1) for t in (t1, t2, n)], axis=-1)  # (W, 3)
    if offset is not None:
        local[:, :2] = 0.0
        local[:, 2] = offset
    return WaistGlue(hit.faces, hit.barycentric.astype(np.float64), local, outward)


def _face_frames(
    vertices: np.ndarray, corners: np.ndarray, outward: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frames (t1, t2, n), each (N, 3), of the faces with corner indices (N, 3); see _face_frame."""
    x0, x1, x2 = (np.asarray(vertices, np.float64)[corners[:, i]] for i in range(3))
    t1 = (x1 - x0) / np.linalg.norm(x1 - x0, axis=-1, keepdims=True)
    n = np.cross(x1 - x0, x2 - x0)
    n = outward * n / np.linalg.norm(n, axis=-1, keepdims=True)
    return t1, np.cross(n, t1), n


def glued_points(glue: WaistGlue, body_vertices: np.ndarray, body_faces: np.ndarray) -> np.ndarray:
    """(W, 3) the glued waistband points on a posed body (Vb, 3) (numpy twin of the kernel)."""
    corners = body_faces[glue.faces]  # (W, 3)
    x = np.asarray(body_vertices, np.float64)[corners]  # (W, 3 corners, 3)
    t1, t2, n = _face_frames(body_vertices, corners, glue.outward)
    surface = (glue.barycentric[:, :, None] * x).sum(1)
    return surface + glue.local[:, :1] * t1 + glue.local[:, 1:2] * t2 + glue.local[:, 2:] * n


class TrappedRelease:
    """Puts cloth vertices deep inside the body back on the skin where they went in.

    A vertex inside one of ``meshes`` farther than ``depth`` from its surface, after a
    frame, goes back to the spot of the body part it is in (the part of its closest face)
    over which it was last seen outside: its anchor on that part, the closest point of the
    part's skin then, carried along as the skin moves; ``offset`` out along that face's
    normal, with the skin's velocity there. Every vertex outside all meshes is anchored
    anew on each part. Cloth pinched into a part comes back on the side it went in from,
    next to its neighbours. Measured on ballet 05_16 (docs/DATASET.md), the closest
    surface point instead can lie on the far side of a thigh, and one anchor for the whole
    body can lie on the other thigh (the cloth was pressed between the two): a vertex put
    there pulls its neighbours through the legs (edge strain p99 13 and 30). A vertex never
    seen outside goes to the closest point.

    Args:
        body: (Vb, 3) the collider's body in the first frame.
        meshes: (F, 3) triangle arrays over the body's vertices, each a closed mesh.
        vertex_part: (Vb,) int64 the part of each body vertex (0 .. P - 1).
        num_vertices: V, cloth vertices.
        depth: metres inside a surface beyond which a vertex is released.
        offset: metres outside the surface it is put.

    Attributes:
        face: (V, P) int64 each vertex's anchor face on each part (-1: none yet), an index
            into ``patches[p]``.
        barycentric: (V, P, 3) float64 the anchor point in that face.
        patches: P (F_p, 3) the faces of each part (over all meshes).
    """

    def __init__(self, body: np.ndarray, meshes: tuple[np.ndarray, ...], vertex_part: np.ndarray,
                 num_vertices: int, depth: float, offset: float) -> None:  # fmt: skip
        from loosefit.geometry.cap import triangle_keys
        from loosefit.geometry.query import Surface

        self.depth, self.offset = float(depth), float(offset)
        every = np.concatenate(meshes)
        first = np.unique(triangle_keys(every)[0], return_index=True)[1]
        faces = every[np.sort(first)]  # each triangle once, as first given
        c = np.asarray(vertex_part, np.int64)[faces]  # (F, 3) each corner's part
        # the part of most corners (of three different parts, the lowest)
        part = np.where(
            c[:, 1] == c[:, 2],
            c[:, 1],
            np.where((c[:, 0] == c[:, 1]) | (c[:, 0] == c[:, 2]), c[:, 0], c.min(1)),
        )
        P = int(np.asarray(vertex_part).max()) + 1
        self.patches = [faces[part == p] for p in range(P)]
        body = np.asarray(body, np.float32)
        self._whole = [Surface(body, f) for f in meshes]
        self._parts = [Surface(body, f) if len(f) else None for f in self.patches]
        self._part_of = [part[_rows_index(faces, f)] for f in meshes]  # mesh face -> part
        self.face = np.full((num_vertices, P), -1, np.int64)
        self.barycentric = np.zeros((num_vertices, P, 3))

    def step(
        self,
        positions: np.ndarray,
        velocities: np.ndarray,
        body: np.ndarray,
        body_before: np.ndarray,
        frame_dt: float,
    ) -> tuple[np.ndarray, np.ndarray, int]:
        """Release the deep vertices after a frame and anchor the ones outside.

        Args:
            positions: (V, 3) cloth vertices after the frame.
            velocities: (V, 3) their velocities.
            body: (Vb, 3) the collider's body at the end of the frame.
            body_before: (Vb, 3) at its start.
            frame_dt: seconds of the frame.

        Returns:
            The new (V, 3) positions and velocities (copies) and how many vertices moved.
        """
        x = np.array(positions, np.float32)
        v = np.array(velocities, np.float32)
        body = np.asarray(body, np.float32)
        for s in (*self._whole, *(p for p in self._parts if p is not None)):
            s.refit(body)
        n = len(x)
        inside = np.zeros(n, bool)
        deep_part = np.full(n, -1, np.int64)  # the part a deep vertex is in
        deep_dist = np.zeros(n)
        for hit, part_of in zip((s.query(x) for s in self._whole), self._part_of, strict=True):
            found = hit.faces >= 0
            inside |= hit.inside & found
            deep = hit.inside & found & (hit.distance > np.maximum(self.depth, deep_dist))
            deep_part[deep] = part_of[hit.faces[deep]]
            deep_dist[deep] = hit.distance[deep]
        where = np.flatnonzero(deep_part >= 0)
        for p in np.unique(deep_part[where]):
            idx = where[deep_part[where] == p]
            face, bary = self.face[idx, p], self.barycentric[idx, p]
            fresh = face < 0
            if fresh.any():  # never seen outside: the closest point of the part
                hit = self._parts[p].query(x[idx[fresh]])
                face[fresh], bary[fresh] = hit.faces, hit.barycentric
            tri = self.patches[p][face]  # (k, 3)
            a, b, c = (body[tri[:, i]] for i in range(3))
            normal = np.cross(b - a, c - a)
            normal /= np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-12)
            w = bary[:, :, None]  # (k, 3, 1)
            x[idx] = (body[tri] * w).sum(1) + self.offset * normal
            v[idx] = ((body[tri] - np.asarray(body_before, np.float32)[tri]) * w).sum(1) / frame_dt
        out = np.flatnonzero(~inside)
        if len(out):
            for p, s in enumerate(self._parts):
                if s is not None:
                    hit = s.query(x[out])
                    self.face[out, p], self.barycentric[out, p] = hit.faces, hit.barycentric
        return x, v, len(where)

    def state(self) -> dict[str, np.ndarray]:
        """The anchors, to save with a run."""
        return {"anchor_face": self.face.copy(), "anchor_barycentric": self.barycentric.copy()}

    def load(self, state: dict[str, np.ndarray]) -> None:
        """Take the anchors of :meth:`state`."""
        self.face = np.array(state["anchor_face"], np.int64)
        self.barycentric = np.array(state["anchor_barycentric"], np.float64)


def _rows_index(rows: np.ndarray, of: np.ndarray) -> np.ndarray:
    """(F',) index into ``rows`` (F, 3) of each triangle of ``of`` (F', 3), as sets."""
    from loosefit.geometry.cap import triangle_keys

    ka, kb = triangle_keys(rows, of)
    order = np.argsort(ka)
    return order[np.searchsorted(ka, kb, sorter=order)]


def release_parts(parts: BodyParts) -> np.ndarray:
    """(Vb,) int64 the body part of each body vertex for :class:`TrappedRelease`: 0 the
    trunk and head, then each limb of :data:`loosefit.eval.body_regions.LIMBS`."""
    out = np.zeros(len(parts.region), np.int64)
    for i, verts in enumerate(parts.limb_vertices.values()):
        out[verts] = i + 1
    return out


def replay_release(
    garment: np.ndarray, collider: np.ndarray, release: TrappedRelease, frame_dt: float
) -> int:
    """Frames of a simulated clip the release of trapped cloth would have changed.

    ``release.step`` over the recorded frames in order, as the simulation runs it (from
    the motion's first frame): where it moves nothing, the clip is the one a run with the
    release on makes (the simulation is deterministic), and ``release`` holds that run's
    anchors after the last frame.

    Args:
        garment: (T, V, 3) the recorded cloth frames.
        collider: (T, Vb, 3) the collider's body in those frames.
        release: a fresh :class:`TrappedRelease` (its anchors are updated).
        frame_dt: seconds per frame.

    Returns:
        How many frames it would have moved cloth in.
    """
    fired = 0
    still = np.zeros(garment.shape[1:], np.float32)
    for t in range(len(garment)):
        fired += release.step(garment[t], still, collider[t], collider[max(t - 1, 0)],
                              frame_dt)[2] > 0  # fmt: skip
    return fired


def substep_schedule(
    waist: np.ndarray, substeps: int, max_substeps: int, max_move: float, widen: int = 2
) -> np.ndarray:
    """Substeps per frame, so that the waistband moves at most ``max_move`` per substep.

    A frame gets ``ceil(d / max_move)`` substeps, clipped to ``[substeps, max_substeps]``,
    where ``d`` is the largest move of a waistband point over that frame and the ``widen``
    frames on either side (so that a fast turn is entered and left with the finer step).

    Args:
        waist: (T, W, 3) the glued waistband points at each frame.
        substeps: the least substeps of a frame.
        max_substeps: the most.
        max_move: metres a waistband point may move in one substep.
        widen: frames on each side whose moves also count.

    Returns:
        (T - 1,) int64: the substeps of the step from frame ``t`` to ``t + 1``.
    """
    waist = np.asarray(waist, np.float64)
    moves = np.linalg.norm(np.diff(waist, axis=0), axis=-1).max(-1)  # (T - 1,)
    if len(moves) and widen > 0:
        padded = np.pad(moves, widen, mode="edge")
        windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * widen + 1)
        moves = windows.max(-1)
    wanted = np.ceil(moves / max_move - 1e-9)
    return np.clip(wanted, substeps, max_substeps).astype(np.int64)


class ClothSimulator:
    """Newton VBD cloth on a deforming body: a static Model, two swapped States, a step a substep.

    One simulator can also run ``K`` clips at once (batched simulation, for a GPU): the
    garment and the body then come with a leading clip axis, and each clip is a world of
    one Newton model, with its own cloth, its own body mesh and its own waistband glue.
    Worlds keep body contacts apart; Newton's cloth self-contact does not look at
    worlds, so each world is also moved to its own cell of a grid, far enough apart that
    no two clips' cloth can meet (offsets added on the way in and taken off on the way
    out: callers see every clip in its own coordinates).

    Args:
        garment_vertices: (V, 3) initial cloth positions, world frame; or (K, V, 3),
            one garment per clip (the same mesh).
        garment_faces: (F, 3) cloth triangles; the initial positions are also the rest shape
            unless ``rest_vertices`` are given.
        waist: (W,) indices of the waistband vertices, glued to the body.
        body_vertices: (Vb, 3) the body at the start, world frame; (K, Vb, 3) batched.
        body_faces: (Fb, 3) triangles of a closed (watertight) body mesh.
        config: the physics.
        frame_dt: seconds per frame; :meth:`step_frame` divides it into ``config.substeps``
            substeps, or as many as it is given.
        bounds: (lower (3,), upper (3,)) a box that holds the body over the whole motion
            (of every clip); contacts are culled outside it. Default: the starting
            bodies' box grown by 2 m.
        loop: ``waist`` is a closed band in order (a waistband, a dress's top band),
            respaced as it is pulled onto the body; False: separate points (a dress's
            straps), each held where it is closest (see :func:`glue_waist`).
        seeds: (K,) each clip's jitter seed (default: ``config.seed`` for all).
        limb_faces: (Fl, 3) triangles of a second closed mesh on the body's vertices (the
            arms cut from ``body_faces``, :meth:`Avatar.cut_limb_faces`), a collider of its
            own with ``config.arm_friction``; None: no such collider.
        rest_vertices: (V, 3) the cloth's rest shape (edge lengths, triangle shapes and
            areas, so masses), in any rigid placement, when it is not the initial positions
            (:attr:`GarmentTemplate.rest_vertices`: a garment fitted to the avatar starts
            draped and keeps its file's rest lengths); None: the initial positions.
    """

    def __init__(
        self,
        garment_vertices: np.ndarray,
        garment_faces: np.ndarray,
        waist: np.ndarray,
        body_vertices: np.ndarray,
        body_faces: np.ndarray,
        config: ClothConfig,
        frame_dt: float,
        bounds: tuple[np.ndarray, np.ndarray] | None = None,
        loop: bool = True,
        seeds: list[int] | None = None,
        limb_faces: np.ndarray | None = None,
        rest_vertices: np.ndarray | None = None,
    ) -> None:
        import newton  # imported here: importing it takes seconds

        self.config = cfg = config
        self.frame_dt = float(frame_dt)
        self.device = wp.get_device(cfg.device)
        garment_vertices = np.asarray(garment_vertices, np.float64)
        self.batched = garment_vertices.ndim == 3
        garments = garment_vertices if self.batched else garment_vertices[None]  # (K, V, 3)
        bodies = np.asarray(body_vertices, np.float32)
        bodies = bodies if self.batched else bodies[None]  # (K, Vb, 3)
        K = self.worlds = len(garments)
        if bodies.ndim != 3 or len(bodies) != K:
            raise LoosefitInputError("ClothSimulator", "body_vertices", f"({K}, Vb, 3)",
                                     f"shape {np.shape(body_vertices)}")  # fmt: skip
        seeds = [cfg.seed] * K if seeds is None else [int(s) for s in seeds]
        if len(seeds) != K:
            raise LoosefitInputError("ClothSimulator", "seeds", f"{K} seeds", len(seeds))
        body_faces = np.ascontiguousarray(body_faces, np.int32)
        waist = np.asarray(waist, np.int64)
        V = self.num_vertices = garments.shape[1]
        if rest_vertices is not None:
            rest_vertices = np.asarray(rest_vertices, np.float64)
            if rest_vertices.shape != (V, 3):
                raise LoosefitInputError("ClothSimulator", "rest_vertices", f"shape ({V}, 3)",
                                         f"shape {rest_vertices.shape}")  # fmt: skip
        self.num_body_vertices = bodies.shape[1]
        if bounds is None:
            bounds = (bodies.min((0, 1)) - 2.0, bodies.max((0, 1)) + 2.0)
        lower = np.asarray(bounds[0], np.float32).reshape(3)
        upper = np.asarray(bounds[1], np.float32).reshape(3)
        # Each clip's cell of the grid: the bounds' size and a metre apart.
        cols = math.ceil(math.sqrt(K))
        cell = (upper - lower) + 1.0
        self.offsets = np.array(
            [[(k % cols) * cell[0], (k // cols) * cell[1], 0.0] for k in range(K)], np.float32
        )  # (K, 3)

        # 1. Glue the waistband to each clip's body, once.
        self.glues = [
            glue_waist(g[waist], b, body_faces, cfg.waist_offset, loop)
            for g, b in zip(garments, bodies, strict=True)
        ]
        self.glue = self.glues[0]

        # 2. The cloth, with a seeded jitter that breaks the template's exact symmetry, and
        #    3. the body: one static mesh shape per clip. Newton mixes contact materials as the
        #    mean of ke and kd and the geometric mean of mu, so the shape's mu is chosen to
        #    give sqrt(self_friction * shape_mu) = body_friction.
        builder = newton.ModelBuilder(gravity=(0.0, 0.0, cfg.gravity))
        shape_mu = cfg.body_friction**2 / cfg.self_friction if cfg.self_friction > 0 else 0.0

        def shape_config(mu: float):
            return newton.ModelBuilder.ShapeConfig(
                ke=cfg.contact_ke,
                kd=cfg.contact_kd,
                mu=mu,
                margin=0.0,
                gap=cfg.body_contact_gap,
                has_shape_collision=False,
                has_particle_collision=True,
            )

        shape_cfg = shape_config(shape_mu)
        limb_cfg = None
        if limb_faces is not None:
            if cfg.arm_friction is None:
                raise LoosefitInputError("ClothSimulator", "config.arm_friction",
                                         "a number when limb_faces are given", "None")  # fmt: skip
            limb_faces = np.ascontiguousarray(limb_faces, np.int32)
            limb_mu = cfg.arm_friction**2 / cfg.self_friction if cfg.self_friction > 0 else 0.0
            limb_cfg = shape_config(limb_mu)
        self._body_meshes = []  # per clip: the body's mesh, then the limbs' if any
        start = np.empty((K * V, 3), np.float32)
        for k in range(K):
            if K > 1:
                builder.begin_world(label=f"clip_{k}")
            off = self.offsets[k].astype(np.float64)
            builder.add_cloth_mesh(
                pos=wp.vec3(0.0, 0.0, 0.0),
                rot=wp.quat_identity(),
                scale=1.0,
                vel=wp.vec3(0.0, 0.0, 0.0),
                # the rest shape (the particles' positions are set to ``start`` below)
                vertices=[
                    wp.vec3(*v)
                    for v in (garments[k] if rest_vertices is None else rest_vertices) + off
                ],  # fmt: skip
                indices=np.asarray(garment_faces, np.int32).ravel().tolist(),
                density=cfg.density,
                tri_ke=cfg.stretch_ke,
                tri_ka=cfg.stretch_ka,
                tri_kd=cfg.stretch_kd,
                edge_ke=cfg.bend_ke,
                edge_kd=cfg.bend_kd,
                particle_radius=cfg.body_contact_distance,
            )
            rng = np.random.default_rng(seeds[k])
            start[k * V : (k + 1) * V] = (
                garments[k] + cfg.jitter * rng.standard_normal(garments[k].shape) + off
            )
            mesh = newton.Mesh(bodies[k] + self.offsets[k], body_faces.ravel(),
                               compute_inertia=False)  # fmt: skip
            self._body_meshes.append([mesh])
            builder.add_shape_mesh(body=-1, mesh=mesh, cfg=shape_cfg)
            if limb_cfg is not None:
                limb = newton.Mesh(bodies[k] + self.offsets[k], limb_faces.ravel(),
                                   compute_inertia=False)  # fmt: skip
                self._body_meshes[-1].append(limb)
                builder.add_shape_mesh(body=-1, mesh=limb, cfg=limb_cfg)
            if K > 1:
                builder.end_world()
        # VBD solves one colour of vertices at a time.
        builder.color(include_bending=cfg.color_bending)

        self.model = model = builder.finalize(device=self.device)
        model.soft_contact_ke = cfg.contact_ke
        model.soft_contact_kd = cfg.contact_kd
        model.soft_contact_mu = cfg.self_friction
        if cfg.flat_rest:
            model.edge_rest_angle.zero_()
        # The shapes' cached boxes are the starting bodies': widen them to the whole motion.
        #    Every shape of a clip (the body, and the arms if they are a mesh of their own).
        per_world = len(self._body_meshes[0])
        if model.shape_collision_aabb_lower.shape[0] != K * per_world:  # assign would truncate
            raise RuntimeError(f"{model.shape_collision_aabb_lower.shape[0]} shapes in the "
                               f"model, expected {K} x {per_world}")  # fmt: skip
        model.shape_collision_aabb_lower.assign(np.repeat(lower[None] + self.offsets, per_world, 0))
        model.shape_collision_aabb_upper.assign(np.repeat(upper[None] + self.offsets, per_world, 0))

        # 4. The waistbands are kinematic: inactive, infinite mass.
        pinned = (np.arange(K)[:, None] * V + waist[None]).ravel()
        flags = model.particle_flags.numpy()
        flags[pinned] &= ~int(newton.ParticleFlags.ACTIVE)
        model.particle_flags.assign(flags)
        inv_mass = model.particle_inv_mass.numpy()
        inv_mass[pinned] = 0.0
        model.particle_inv_mass.assign(inv_mass)

        # 5. Contacts, solver, the two states.
        self.pipeline = newton.CollisionPipeline(model, soft_contact_gap=cfg.body_contact_gap)
        self.contacts = self.pipeline.contacts()
        self.solver = newton.solvers.SolverVBD(
            model,
            iterations=cfg.iterations,
            integrate_with_external_rigid_solver=True,  # the body moves outside the solver
            particle_enable_self_contact=cfg.self_contact,
            particle_self_contact_margin=cfg.self_contact_margin,
            particle_self_contact_gap=cfg.self_contact_gap,
            particle_rest_shape_contact_exclusion_radius=cfg.self_contact_rest_exclusion,
        )
        self.state_0 = model.state()
        self.state_1 = model.state()
        self.control = model.control()
        self.state_0.particle_q.assign(start)
        self.state_1.particle_q.assign(start)

        # 6. Device buffers for the bodies' frame and the glue, per clip.
        d = self.device
        self._body_faces = wp.array(body_faces, dtype=wp.vec3i, device=d)
        self._body_start = [wp.array(b + o, dtype=wp.vec3, device=d)
                            for b, o in zip(bodies, self.offsets, strict=True)]  # fmt: skip
        self._body_end = [wp.array(b + o, dtype=wp.vec3, device=d)
                          for b, o in zip(bodies, self.offsets, strict=True)]  # fmt: skip
        self._glue_arrays = [
            (
                wp.array(g.faces.astype(np.int32), dtype=wp.int32, device=d),
                wp.array(g.barycentric.astype(np.float32), dtype=wp.vec3, device=d),
                wp.array(g.local.astype(np.float32), dtype=wp.vec3, device=d),
                g.outward,
                wp.array((waist + k * V).astype(np.int32), dtype=wp.int32, device=d),
            )
            for k, g in enumerate(self.glues)
        ]
        self._damp_factor = wp.ones(1, dtype=float, device=d)
        self._graphs: dict = {}  # recorded substeps, by substep count and swap parity
        self._substeps = cfg.substeps  # of the frame being stepped
        self._swaps = 0
        self._pose_body(1.0)
        self._pin_waist()

    # -- one substep at a time --------------------------------------------------

    def _pose_body(self, alpha: float) -> None:
        for k, shapes in enumerate(self._body_meshes):
            for shape in shapes:
                mesh = shape.mesh
                wp.launch(
                    _pose_body_kernel,
                    dim=self.num_body_vertices,
                    inputs=[self._body_start[k], self._body_end[k], alpha, 1.0 / self.frame_dt],
                    outputs=[mesh.points, mesh.velocities],
                    device=self.device,
                )
                mesh.refit()

    def _pin_waist(self) -> None:
        for (body, *_), (faces, bary, local, outward, particles) in zip(
            self._body_meshes, self._glue_arrays, strict=True
        ):
            wp.launch(
                _pin_waist_kernel,
                dim=len(particles),
                inputs=[
                    body.mesh.points,
                    self._body_faces,
                    faces,
                    bary,
                    local,
                    outward,
                    particles,
                ],  # fmt: skip
                outputs=[self.state_0.particle_q, self.state_1.particle_q],
                device=self.device,
            )

    def _substep(self) -> None:
        """One substep once the body is posed: device work only, so that a graph can record it."""
        dt = self.frame_dt / self._substeps
        self._pin_waist()
        self.pipeline.collide(self.state_0, self.contacts)
        self.solver.step(self.state_0, self.state_1, self.control, self.contacts, dt)
        wp.launch(
            _damp_kernel,
            dim=self.worlds * self.num_vertices,
            inputs=[self._damp_factor],
            outputs=[self.state_1.particle_qd],
            device=self.device,
        )

    def step_frame(
        self,
        body_start: np.ndarray,
        body_end: np.ndarray,
        damping: float | None = None,
        substeps: int | None = None,
    ) -> None:
        """Advance one frame while the body moves linearly from ``body_start`` to ``body_end``.

        Args:
            body_start: (Vb, 3) body vertices at the start of the frame; (K, Vb, 3) batched.
            body_end: (Vb, 3) body vertices at the end of the frame; (K, Vb, 3) batched.
            damping: velocity decay rate, 1/s (default ``config.air_damping``).
            substeps: solver steps for this frame (default ``config.substeps``).
        """
        cfg = self.config
        n = cfg.substeps if substeps is None else int(substeps)
        if n < 1:
            raise ValueError(f"substeps must be >= 1, got {n}")
        self._substeps = n
        rate = cfg.air_damping if damping is None else damping
        self._damp_factor.fill_(math.exp(-rate * self.frame_dt / n))
        starts = np.asarray(body_start, np.float32).reshape(self.worlds, -1, 3)
        ends = np.asarray(body_end, np.float32).reshape(self.worlds, -1, 3)
        for k in range(self.worlds):
            self._body_start[k].assign(np.ascontiguousarray(starts[k] + self.offsets[k]))
            self._body_end[k].assign(np.ascontiguousarray(ends[k] + self.offsets[k]))
        self.solver.rebuild_bvh(self.state_0)  # self-contact BVH, rebuilt once a frame
        for s in range(n):
            # Pose the body for the end of the substep before detecting contacts against it.
            # (Outside any graph: a CPU graph does not replay wp.Mesh.refit.)
            self._pose_body((s + 1) / n)
            if cfg.capture and self._swaps >= 2:
                # One graph per direction of the swap, state_0 -> state_1 and back, recorded
                # after a plain substep each (which allocates whatever the solver allocates
                # lazily).
                # The substep length is baked into a graph: one pair per substep count.
                slot = (n, self._swaps % 2)
                if slot not in self._graphs:
                    with wp.ScopedCapture(device=self.device) as capture:
                        self._substep()
                    self._graphs[slot] = capture.graph
                wp.capture_launch(self._graphs[slot])
            else:
                self._substep()
            self.state_0, self.state_1 = self.state_1, self.state_0
            self._swaps += 1

    def _per_clip(self, x: np.ndarray, sign: float) -> np.ndarray:
        """(K * V, 3) particle positions to (K, V, 3) or (V, 3), offsets taken off (sign -1)."""
        x = x.reshape(self.worlds, self.num_vertices, 3) + sign * self.offsets[:, None]
        return x if self.batched else x[0]

    @property
    def positions(self) -> np.ndarray:
        """(V, 3) float32 current cloth positions (a copy); (K, V, 3) batched."""
        return self._per_clip(self.state_0.particle_q.numpy(), -1.0).astype(np.float32)

    def get_state(self) -> tuple[np.ndarray, np.ndarray]:
        """(V, 3) float32 positions and (V, 3) float32 velocities (a leading K batched): all
        the solver carries over."""
        qd = self.state_0.particle_qd.numpy().reshape(self.worlds, self.num_vertices, 3)
        return self.positions, (qd if self.batched else qd[0]).copy()

    def set_state(self, positions: np.ndarray, velocities: np.ndarray) -> None:
        """Continue from a state taken by :meth:`get_state` (after the same number of frames)."""
        q = np.asarray(positions, np.float32).reshape(self.worlds, self.num_vertices, 3)
        q = (q + self.offsets[:, None]).reshape(-1, 3)
        qd = np.asarray(velocities, np.float32).reshape(-1, 3)
        for state in (self.state_0, self.state_1):
            state.particle_q.assign(np.ascontiguousarray(q))
            state.particle_qd.assign(np.ascontiguousarray(qd))


# -- driving it with a motion -----------------------------------------------------


def attached_loop(template: GarmentTemplate) -> bool:
    """Whether a garment is held by a closed band (a waistband: ``meta["attachment"]``
    "loop", the default) or by separate points ("points": a dress's straps)."""
    return (template.meta or {}).get("attachment", "loop") == "loop"


def _check_template(template: GarmentTemplate) -> None:
    src = f"garment '{template.name}'"
    if len(template.waist) == 0:
        raise LoosefitInputError(
            src, "waist", "at least one waistband vertex to attach to the body", "none",
            hint="a garment with no waistband would fall off the body",
        )  # fmt: skip


def _guard(positions: np.ndarray, body: np.ndarray, limit: float, where: str) -> None:
    """Raise :class:`SimulationError` on NaN or a vertex more than ``limit`` from the body's box."""
    bad = ~np.isfinite(positions).all(-1)
    if bad.any():
        raise SimulationError(
            f"cloth simulation diverged at {where}: {int(bad.sum())} NaN vertices"
        )
    lo, hi = body.min(0), body.max(0)
    gap = np.linalg.norm(positions - np.clip(positions, lo, hi), axis=-1)
    if gap.max() > limit:
        raise SimulationError(
            f"cloth simulation diverged at {where}: a vertex is {gap.max():.1f} m from the body"
        )


def _frame_name(k: int, n_settle: int, n_pre: int) -> str:
    if k < n_settle:
        return f"settle frame {k}"
    if k < n_pre:
        return f"blend frame {k - n_settle}"
    return f"motion frame {k - n_pre}"


# ClothConfig fields added after 2026-11-26, with the value that does what the solver did
# before they existed: at that value a field stays out of the run key, so that a run saved
# before it existed still resumes. Every new field goes here. (Adding release_depth to the
# key cost the dance data set two clips' saved frames, 3.5 core-hours.)
RUN_KEY_SINCE: dict[str, object] = {}


def _run_key(body: np.ndarray, template: GarmentTemplate, config: ClothConfig) -> str:
    """A fingerprint of everything that decides a simulation's frames (but the device's
    rounding)."""
    h = hashlib.sha256()
    for a in (body[:: max(len(body) // 64, 1)], template.vertices, template.faces, template.waist):
        h.update(np.ascontiguousarray(a).tobytes())
    if template.rest_vertices is not None:  # a template without them keeps its key
        h.update(np.ascontiguousarray(template.rest_vertices).tobytes())
    # the release of trapped cloth does not enter it: a run it never changed is the same
    # (the resume checks that; see simulate_batch)
    # Nor does the device: a clip begun on a GPU goes on from its saved state on the CPU and
    # vice versa (the physics is the same; only the rounding differs). It is normalised to
    # "cpu" rather than dropped, so that a run saved on the CPU keeps the key it had.
    fields = asdict(replace(config, release_depth=None, device="cpu"))
    fields = {k: v for k, v in fields.items() if k not in RUN_KEY_SINCE or v != RUN_KEY_SINCE[k]}
    h.update(str((body.shape, sorted(fields.items()))).encode())
    return h.hexdigest()[:32]


def _resumed_release(
    saved: dict,
    config: ClothConfig,
    colliders: list[np.ndarray],
    releases: list[TrappedRelease] | None,
    n_pre: int,
    frame_dt: float,
    released: list[np.ndarray],
) -> tuple[dict | None, list[np.ndarray]]:
    """A saved run's state for the release of trapped cloth, or None to start over.

    The run key leaves ``release_depth`` out, so a run saved with another release is found
    too: it is taken when the release never changed it, judged by the frames it recorded
    (:func:`replay_release`, which also gives the anchors) or the counts it saved.
    ``releases`` (one per clip, None when the release is off) take the saved run's anchors.

    Returns:
        ``saved`` (None: start over) and each clip's released counts per frame.
    """
    K = len(colliders)
    stored = float(saved.get("release_depth", np.nan))
    stored = None if math.isnan(stored) else stored
    counts = [np.asarray(saved.get(f"released_{c}", r)).copy() for c, r in enumerate(released)]
    if stored == config.release_depth:
        for c, release in enumerate(releases or []):
            if f"anchor_face_{c}" in saved:
                release.load({k: saved[f"{k}_{c}"] for k in release.state()})
        return saved, counts
    if any(r.any() for r in counts):
        return None, released  # the saved run's release moved cloth
    recorded = max(int(saved["frame"]) - n_pre + 1, 0)
    for c, release in enumerate(releases or []):
        g = saved[f"garment_{c}" if K > 1 else "garment"][:recorded]
        if replay_release(g, colliders[c][n_pre : n_pre + len(g)], release, frame_dt):
            return None, released
    return saved, counts


def _write_resume(path: Path, **arrays) -> None:
    with atomic_path(path) as tmp:
        np.savez(tmp, **arrays)


def _read_resume(path: Path, key: str, total: int) -> dict | None:
    """The saved state of the same run, or None (a missing, other or unreadable file)."""
    try:
        with np.load(path, allow_pickle=False) as data:
            if str(data["key"]) != key or not 0 < int(data["frame"]) <= total:
                return None
            return {k: data[k] for k in data.files}
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
        return None


def _limb_faces(avatar: Avatar, config: ClothConfig) -> np.ndarray | None:
    """(Fl, 3) the arms' own collider (``config.arm_friction``), or None."""
    if config.arm_friction is None or config.arm_collision is True:
        return None
    return avatar.cut_limb_faces(config.arm_collision).cpu().numpy()


def simulate(
    avatar: Avatar,
    template: GarmentTemplate,
    motion: Motion,
    config: ClothConfig | None = None,
    progress: Callable[[int, int], None] | None = None,
    resume: str | Path | None = None,
    resume_every: int = 50,
) -> SimResult:
    """Simulate a garment on the avatar through a motion.

    Args:
        avatar: the :class:`~loosefit.body.avatar.Avatar` the motion drives.
        template: the garment in the avatar's rest frame (root joint at the origin),
            e.g. from :func:`~loosefit.dress.fit_skirt`.
        motion: T frames on the avatar's skeleton.
        config: the physics (default :class:`ClothConfig`).
        progress: called as ``progress(done, total)`` after every simulated frame.
        resume: a ``.npz`` file where the run saves its state (atomically, every
            ``resume_every`` frames) and from which a killed run of the same body
            motion, garment and configuration continues; deleted when the run
            ends. A file of another run is ignored and overwritten.
        resume_every: frames between saves.

    Returns:
        A :class:`SimResult` whose ``garment_vertices`` (T, V, 3) are in the world
        frame, frame ``t`` matching motion frame ``t``.

    Raises:
        LoosefitInputError: a template without waistband, a motion on other joints.
        SimulationError: NaN or a vertex more than ``config.max_distance`` from the body.
    """
    return simulate_batch(avatar, template, [motion], config, progress, resume, resume_every)[0]


@dataclass
class Timeline:
    """A clip's body over the simulation's timeline: settle, blend, then the motion.

    Attributes:
        body: (P + T, Vb, 3) float32 the posed body (what every measure takes).
        collider: (P + T, Vb, 3) float32 what the cloth collides with: the posed body, its
            limbs pressed out of the rest of it where the pose folds into itself
            (``ClothConfig.flatten_overlaps``; else ``body`` itself).
        pressed: (P + T,) int64 collider vertices pressed per frame.
        overlap: (P + T,) m, the deepest limb vertex inside the rest of the body per frame.
        n_settle: frames of settling (the first frames of the preroll).
        n_pre: P, frames before the motion's first (settle and blend).
        root_pose: (4, 4) float64 the root joint's transform in the first frame.
    """

    body: np.ndarray
    collider: np.ndarray
    pressed: np.ndarray
    overlap: np.ndarray
    n_settle: int
    n_pre: int
    root_pose: np.ndarray


def timeline(
    avatar: Avatar, motion: Motion, config: ClothConfig, parts: BodyParts | None = None
) -> Timeline:
    """The body a clip's simulation meets, frame by frame (:class:`Timeline`); ``parts``:
    the avatar's :func:`~loosefit.eval.body_regions.body_parts` with the config's arms
    (built here when needed and not given)."""
    pre_rot, pre_root, n_settle = preroll(
        motion, avatar.floor_height, config.settle_seconds, config.blend_seconds,
        config.settle_at_start,
    )  # fmt: skip
    rotations = torch.from_numpy(np.concatenate([pre_rot, motion.rotations]))
    root = torch.from_numpy(np.concatenate([pre_root, motion.root_translation]))
    with torch.no_grad():
        posed = avatar.pose(rotations, root)
    body = posed.vertices.detach().to("cpu", torch.float32).numpy()  # (P + T, Vb, 3)
    root_pose = posed.joint_transforms[0, 0].detach().double().cpu().numpy()  # (4, 4)
    collider, pressed, overlap = body, np.zeros(len(body), np.int64), np.zeros(len(body))
    if config.flatten_overlaps:
        from loosefit.sim.overlap import flatten_overlaps

        flat = flatten_overlaps(body, parts or collider_parts(avatar, config), config.overlap_inset)
        collider, pressed, overlap = flat.vertices, flat.moved, flat.depth
    return Timeline(body, collider, pressed, overlap, n_settle, len(pre_rot), root_pose)


def collider_parts(avatar: Avatar, config: ClothConfig) -> BodyParts:
    """The avatar's :class:`~loosefit.eval.body_regions.BodyParts` with the arms the cloth
    meets (what the pressing of overlaps and the release of trapped cloth take)."""
    from loosefit.eval.body_regions import body_parts

    return body_parts(avatar, arms=config.colliding_arms)


def collider_meshes(
    avatar: Avatar, config: ClothConfig
) -> tuple[np.ndarray, np.ndarray | None, tuple[np.ndarray, ...]]:
    """The body's collider faces (F, 3), the arms' own mesh (F', 3) where they collide as
    one (else None), and both as the tuple of closed meshes the cloth meets."""
    body_faces = avatar.collider_faces(arms=config.arm_collision).cpu().numpy()
    limb_faces = _limb_faces(avatar, config)
    meshes = (body_faces,) if limb_faces is None else (body_faces, limb_faces)
    return body_faces, limb_faces, meshes


def simulate_batch(
    avatar: Avatar,
    template: GarmentTemplate,
    motions: list[Motion],
    config: ClothConfig | None = None,
    progress: Callable[[int, int], None] | None = None,
    resume: str | Path | None = None,
    resume_every: int = 50,
    seeds: list[int] | None = None,
) -> list[SimResult]:
    """Simulate a garment through several motions at once, each clip a world of one model.

    What :func:`simulate` does for one clip, for ``K`` clips stepped together (on a GPU,
    K clips cost little more than one). Every frame gets the substeps the most
    demanding clip needs then (:func:`substep_schedule`, the maximum over the clips),
    so a clip may get more substeps than it would alone; a clip that ends before the
    longest holds its last pose until the batch ends. The motions must share a frame
    rate. Timings are the batch's, shared evenly among its clips
    (``seconds_per_frame`` is the batch's seconds per frame divided by K).

    Args:
        avatar, template, config, resume, resume_every: as :func:`simulate`.
        motions: K motions on the avatar's skeleton, all at one frame rate.
        progress: called as ``progress(done, total)`` after every batch frame.
        seeds: (K,) each clip's jitter seed (default: ``config.seed`` for all).

    Returns:
        K :class:`SimResult`, one per motion, in order.

    Raises:
        LoosefitInputError: no motion, motions at different frame rates, a template
            without waistband, a motion on other joints.
        SimulationError: NaN or a vertex too far from the body in any clip (the message
            names the clip).
    """
    config = config or ClothConfig()
    if not motions:
        raise LoosefitInputError("simulate_batch", "motions", "at least one motion", "none")
    fps = float(motions[0].fps)
    for m in motions:
        avatar.check_motion(m)
        if abs(float(m.fps) - fps) > 1e-9:
            raise LoosefitInputError(f"motion '{m.name}'", "fps", f"{fps} (the batch's)", m.fps)
    _check_template(template)
    K = len(motions)

    # 1. Each body over its whole timeline: settle, blend, motion.
    needs_parts = config.flatten_overlaps or config.release_depth is not None
    parts = collider_parts(avatar, config) if needs_parts else None  # once for all clips
    lines = [timeline(avatar, motion, config, parts) for motion in motions]
    bodies, colliders = [t.body for t in lines], [t.collider for t in lines]
    pressed, overlap = [t.pressed for t in lines], [t.overlap for t in lines]
    n_pre, n_settle = lines[0].n_pre, lines[0].n_settle
    garments = [
        template.vertices.astype(np.float64) @ t.root_pose[:3, :3].T + t.root_pose[:3, 3]
        for t in lines
    ]
    body_faces, limb_faces, meshes = collider_meshes(avatar, config)
    measured_faces = meshes[0] if len(meshes) == 1 else meshes
    totals = [len(b) - 1 for b in bodies]  # frames each clip steps
    total = max(totals)

    # 2. The simulator, with contact culling widened to the whole motions.
    t0 = time.perf_counter()
    lower = np.min([b.min((0, 1)) for b in bodies], 0) - 2.0
    upper = np.max([b.max((0, 1)) for b in bodies], 0) + 2.0
    start_bodies = np.stack([b[0] for b in colliders])
    sim = ClothSimulator(
        np.stack(garments) if K > 1 else garments[0], template.faces, template.waist,
        start_bodies if K > 1 else start_bodies[0], body_faces, config,
        frame_dt=1.0 / fps, bounds=(lower, upper), loop=attached_loop(template), seeds=seeds,
        limb_faces=limb_faces, rest_vertices=template.rest_vertices,
    )  # fmt: skip
    t_build = time.perf_counter() - t0
    schedule = np.full(total, config.substeps, np.int64)
    if config.max_substeps > config.substeps:
        for glue, body, n in zip(sim.glues, colliders, totals, strict=True):
            waist = np.stack([glued_points(glue, b, body_faces) for b in body])  # (P + T, W, 3)
            own = substep_schedule(
                waist, config.substeps, config.max_substeps, config.substep_waist_move
            )
            schedule[:n] = np.maximum(schedule[:n], own)

    def body_at(k: int) -> np.ndarray:
        """(Vb, 3) or (K, Vb, 3): each clip's body at timeline frame k (its last once over)."""
        at = np.stack([b[min(k, len(b) - 1)] for b in colliders])
        return at if K > 1 else at[0]

    # 3. Step through the timeline; record from the motions' first frame on.
    outs = [np.empty((m.num_frames, template.num_vertices, 3), np.float32) for m in motions]
    settled = sim.positions.reshape(K, -1, 3).copy()
    first, t_before = 0, 0.0
    resume = Path(resume) if resume is not None else None
    key = ""
    if resume is not None:
        keys = [_run_key(b, template, replace(config, seed=s))
                for b, s in zip(bodies, seeds or [config.seed] * K, strict=True)]  # fmt: skip
        key = keys[0] if K == 1 else hashlib.sha256("".join(keys).encode()).hexdigest()[:32]
    saved = _read_resume(resume, key, total) if resume is not None else None
    released = [np.zeros(len(b), np.int64) for b in bodies]  # cloth vertices put back, per frame

    def fresh_releases() -> list[TrappedRelease] | None:
        if config.release_depth is None:
            return None
        where = release_parts(parts)
        return [TrappedRelease(c[0], meshes, where, template.num_vertices, config.release_depth,
                               config.body_contact_distance) for c in colliders]  # fmt: skip

    releases = fresh_releases()
    if saved is not None:
        saved, released = _resumed_release(
            saved, config, colliders, releases, n_pre, 1.0 / fps, released
        )
        if saved is None:
            releases = fresh_releases()
    if saved is not None:
        first, t_before = int(saved["frame"]), float(saved["seconds"])
        shape = (K, template.num_vertices, 3) if K > 1 else (template.num_vertices, 3)
        sim.set_state(saved["positions"].reshape(shape), saved["velocities"].reshape(shape))
        settled = saved["settled"].reshape(K, -1, 3)
        recorded = max(first - n_pre + 1, 0)
        for c, out in enumerate(outs):
            n = min(recorded, len(out))
            out[:n] = saved[f"garment_{c}" if K > 1 else "garment"][:n]
    t0 = time.perf_counter()
    for k in range(first, total):
        if resume is not None and k > first and k % resume_every == 0:
            q, qd = sim.get_state()
            recorded = max(k - n_pre + 1, 0)
            garment = (
                {f"garment_{c}": out[: min(recorded, len(out))] for c, out in enumerate(outs)}
                if K > 1 else {"garment": outs[0][:recorded]}
            )  # fmt: skip
            held = {  # the skin anchors of the release of trapped cloth, where it is on
                f"{k}_{c}": a for c, r in enumerate(releases or []) for k, a in r.state().items()
            }
            held.update({f"released_{c}": r for c, r in enumerate(released)})
            depth = config.release_depth
            held["release_depth"] = np.float64(np.nan if depth is None else depth)
            _write_resume(
                resume, key=np.array(key), frame=np.int64(k), positions=q, velocities=qd,
                settled=settled if K > 1 else settled[0],
                seconds=np.float64(t_before + time.perf_counter() - t0), **garment, **held,
            )  # fmt: skip
        settling = k + 1 < n_settle
        damping = config.settle_damping if settling else None
        sim.step_frame(body_at(k), body_at(k + 1), damping, substeps=int(schedule[k]))
        if releases is not None and k + 1 >= n_pre:  # in the motion's frames
            q, qd = (a.reshape(K, -1, 3) for a in sim.get_state())
            count = 0
            for c, body in enumerate(colliders):
                if k >= totals[c]:
                    continue
                q[c], qd[c], n = releases[c].step(q[c], qd[c], body[k + 1], body[k], 1.0 / fps)
                released[c][k + 1] = n
                count += n
            if count:
                sim.set_state(q if K > 1 else q[0], qd if K > 1 else qd[0])
        positions = sim.positions.reshape(K, -1, 3)
        for c, (body, n) in enumerate(zip(bodies, totals, strict=True)):
            if k >= n:
                continue  # this clip is over: it holds its last pose
            where = _frame_name(k + 1, n_settle, n_pre)
            _guard(positions[c], body[k + 1], config.max_distance,
                   where if K == 1 else f"{where} of clip '{motions[c].name}'")  # fmt: skip
            if k + 1 >= n_pre:
                outs[c][k + 1 - n_pre] = positions[c]
        if k + 1 == n_settle - 1:
            settled = positions.copy()
        if progress is not None:
            progress(k + 1, total)
    t_sim = t_before + time.perf_counter() - t0
    if resume is not None:
        resume.unlink(missing_ok=True)

    results = []
    for c, (motion, body, n) in enumerate(zip(motions, bodies, totals, strict=True)):
        stats = {
            "vertices": template.num_vertices,
            "body_vertices": int(body.shape[1]),
            "frames_simulated": n,
            "substeps_mean": float(schedule[:n].mean()) if n else float(config.substeps),
            "substeps_max": int(schedule[:n].max()) if n else config.substeps,
            "build_seconds": t_build / K,
            "simulate_seconds": t_sim / K,
            "batch": K,
            "batch_frames": total,
            "resumed_frame": first,  # the timeline frame a killed run went on from (0: none)
            # the pose folding into itself: frames whose collider was pressed, the deepest
            # limb vertex inside the rest of the body (m)
            "overlap_frames": int((pressed[c][n_pre:] > 0).sum()),
            # cloth put back on the skin from deeper than release_depth: frames, vertices
            "released_frames": int((released[c][n_pre:] > 0).sum()),
            "released_vertices": int(released[c][n_pre:].sum()),
            "overlap_depth_max": float(overlap[c][n_pre:].max(initial=0.0)),
            "config": asdict(config),
        }
        results.append(SimResult(
            garment_vertices=outs[c],
            faces=template.faces.copy(),
            fps=motion.fps,
            seconds_per_frame=t_sim / K / max(total, 1),
            preroll_frames=n_pre,
            settled_vertices=settled[c],
            quality=quality(outs[c], template, body[n_pre:], measured_faces, motion.fps),
            stats=stats,
        ))  # fmt: skip
    return results


def settle(
    avatar: Avatar,
    template: GarmentTemplate,
    config: ClothConfig | None = None,
    fps: float = 30.0,
    progress: Callable[[int, int], None] | None = None,
) -> np.ndarray:
    """The garment draped on the rest pose: the settle phase of :func:`simulate` on its own.

    This is where every simulated clip starts from (the same drape, moved to where
    the motion starts), and so where a learned rollout starts from.

    Args:
        avatar: the body.
        template: the garment in the avatar's rest frame.
        config: the physics (``settle_seconds``, ``settle_damping``, ...).
        fps: the frame rate of the clips (the settle phase steps whole frames).
        progress: called as ``progress(done, total)`` after every frame of the drape.

    Returns:
        (V, 3) float32 vertices in the rest pose's root frame (root joint at the
        origin, facing -Y).
    """
    config = config or ClothConfig()
    _check_template(template)
    J = len(avatar.joint_names)
    rest = torch.eye(3).expand(1, J, 3, 3).contiguous()
    root = torch.tensor([[0.0, 0.0, avatar.floor_height]])
    with torch.no_grad():
        body = avatar.pose(rest, root).vertices[0].detach().to("cpu", torch.float32).numpy()
    garment = template.vertices.astype(np.float64) + root.numpy()[0]
    sim = ClothSimulator(
        garment, template.faces, template.waist, body,
        avatar.collider_faces(arms=config.arm_collision).cpu().numpy(), config,
        frame_dt=1.0 / fps, bounds=(body.min(0) - 2.0, body.max(0) + 2.0),
        loop=attached_loop(template), limb_faces=_limb_faces(avatar, config),
        rest_vertices=template.rest_vertices,
    )  # fmt: skip
    n_settle = int(round(config.settle_seconds * fps)) + 1
    for k in range(n_settle - 1):
        sim.step_frame(body, body, config.settle_damping)
        _guard(sim.positions, body, config.max_distance, f"settle frame {k + 1}")
        if progress is not None:
            progress(k + 1, n_settle - 1)
    return (sim.positions - root.numpy()).astype(np.float32)
