"""How a garment is simulated: :class:`ClothConfig`, the physics the stepper and its drivers read.

Units: metres, kilograms, seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from loosefit.errors import LoosefitInputError


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
    # m: a frame in which the body at the garment's height (the legs, the hips, a hand at the
    # skirt) moves more than this per substep also gets more substeps, so that the cloth,
    # which moves at most 0.85 (self_contact_margin + self_contact_gap) a substep, can keep
    # ahead of a fast leg; None: only the waistband counts
    substep_body_move: float | None = None
    iterations: int = 5  # VBD iterations per substep
    # where each substep's VBD iterations start (loosefit.sim.vbd): "inertia", Newton's
    # inertial prediction (every vertex falls freely for a substep); "adaptive", the VBD
    # paper's guess from the last substep's acceleration along gravity (a hanging vertex
    # starts where it is), which leaves less stretch for the iterations to take back
    initial_guess: str = "inertia"
    # Chebyshev's acceleration of the VBD iterations for this spectral radius (0: off): each
    # iteration after the first overshoots along the last two (VBD paper, section 3.7)
    chebyshev_rho: float = 0.0
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
    # docs/design/PENETRATION.md)
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
    # than 5 mm inside the body against 54, edge strain as without arms; docs/use/DATASET.md).
    # Nothing is cut with arm_collision true, and this does not apply.
    arm_friction: float | None = 0.0
    # m: after each frame of the motion, a cloth vertex deeper than this inside the body
    # (against each mesh the cloth collides with) is put back on the skin of the part it is
    # in, where it went in, moving with it (TrappedRelease): cloth pinched between two body
    # parts (the thighs crossing in a turning leap, ballet 05_16) can sink past the
    # contact's reach and stay inside for the rest of the clip (81 of 122 frames, 6.4 cm
    # deep; four times the reach did not free it). None: never.
    # Measured there (docs/use/DATASET.md), it tears the cloth wherever it puts the vertices
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
    # cloth-cloth contact detection passes a substep: 2 before and after the solver's forward
    # step (Newton's default), 1 before it only (each pass is about 8% of a frame on a CPU)
    self_contact_passes: int = 2
    # timeline
    settle_seconds: float = 1.0  # drape under gravity on the rest pose before anything moves
    blend_seconds: float = 0.5  # the body blends from the rest pose into the motion's first frame
    # settle where the motion starts (the root's floor position and heading) rather than at
    # the origin facing -Y, so the blend never drags the skirt across the room
    settle_at_start: bool = True
    # every clip starts from one drape settled on the rest pose (the data set's rest_drape.npy,
    # or settled once for a batch), placed where its motion starts, rather than settling
    # on its own: the settle phase once a data set, not once a clip
    settle_once: bool = False
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
            raise LoosefitInputError(
                src, "flatten_overlaps", "true or false", repr(self.flatten_overlaps)
            )
        if self.arm_collision not in (False, True, "upper"):
            raise LoosefitInputError(
                src, "arm_collision", "false, true or 'upper'", repr(self.arm_collision)
            )
        if self.initial_guess not in ("inertia", "adaptive"):
            raise LoosefitInputError(
                src, "initial_guess", "'inertia' or 'adaptive'", repr(self.initial_guess)
            )
        rho = self.chebyshev_rho
        if isinstance(rho, bool) or not isinstance(rho, int | float) or not 0 <= rho < 1:
            raise LoosefitInputError(src, "chebyshev_rho", "a number in [0, 1)", repr(rho))
        if self.self_contact_passes not in (1, 2) or isinstance(self.self_contact_passes, bool):
            raise LoosefitInputError(
                src, "self_contact_passes", "1 or 2", repr(self.self_contact_passes)
            )
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
            "stretch_ka",
            "stretch_kd",
            "bend_ke",
            "bend_kd",
            "air_damping",
            "settle_damping",
            "jitter",
            "body_contact_gap",
            "contact_kd",
            "body_friction",
            "self_friction",
            "self_contact_margin",
            "self_contact_gap",
            "self_contact_rest_exclusion",
            "settle_seconds",
            "blend_seconds",
        )
        # None turns these off; a number is checked as the others
        optional_positive = ("release_depth", "substep_body_move")
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
                raise LoosefitInputError(
                    src, name, ("None or " if name in optional else "") + want, repr(value)
                )
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
