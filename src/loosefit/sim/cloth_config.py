"""How a garment is simulated: :class:`ClothConfig`, the physics the stepper and its drivers read.

Units: metres, kilograms, seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from loosefit.errors import LoosefitInputError


@dataclass
class ClothConfig:
    """How the garment is simulated. Units: metres, kilograms, seconds.

    Why the defaults hold the values they do: docs/design/notes/cloth_config.md.
    """

    # time stepping
    substeps: int = 20  # solver steps per motion frame (dt = 1/600 s at 30 fps)
    max_substeps: int = 60  # the most substeps a fast frame gets (substep_schedule)
    substep_waist_move: float = 0.004  # m of waistband travel a substep before a frame gets more
    # m of body travel at the garment's height a substep before a frame gets more; None: off
    substep_body_move: float | None = None
    iterations: int = 5  # VBD iterations per substep
    # where each substep's VBD iterations start: "inertia" (free fall) or "adaptive" (VBD paper)
    initial_guess: str = "inertia"
    chebyshev_rho: float = 0.0  # spectral radius of Chebyshev's acceleration of VBD (0: off)
    # fabric
    density: float = 0.15  # kg/m^2, mass of the fabric per area
    stretch_ke: float = 1.0e3  # N/m, membrane shear stiffness (Newton's tri_ke, Lame mu)
    stretch_ka: float = 1.0e3  # N/m, membrane area stiffness (Newton's tri_ka, Lame lambda)
    stretch_kd: float = 1.0e-2  # s, membrane strain-rate damping (Newton's tri_kd)
    bend_ke: float = 1.0e-2  # N m/rad per metre of edge, dihedral bending stiffness (edge_ke)
    bend_kd: float = 1.0e-3  # bending damping (Newton's edge_kd)
    flat_rest: bool = True  # bending rest angle 0 (flat fabric), not the template's draped shape
    color_bending: bool = False  # colour the mesh so that no bending edge joins one colour
    # forces on the cloth
    gravity: float = -9.81  # m/s^2 along +Z
    air_damping: float = 0.3  # 1/s, velocities decay as exp(-air_damping t): a stand-in for drag
    settle_damping: float = 5.0  # 1/s, the same while settling, so the drape comes to rest
    # contact with the body
    body_contact_distance: float = 0.004  # m, cloth vertices are kept this far outside the body
    body_contact_gap: float = 0.04  # m, extra reach of body-contact detection beyond the distance
    contact_ke: float = 1.0e4  # N/m, contact stiffness (cloth-body and cloth-cloth)
    contact_kd: float = 1.0e-2  # N s/m, contact damping (cloth-body and cloth-cloth)
    body_friction: float = 0.3  # Coulomb friction between cloth and body
    # the arms collide with the cloth: False, True (from the shoulder) or "upper" (to the elbow)
    arm_collision: bool | str = False
    # Coulomb friction of the arms cut from the body as a collider of their own; None: no such
    arm_friction: float | None = 0.0
    # m: a vertex deeper inside the body after a frame goes back where it went in; None: never
    release_depth: float | None = None
    flatten_overlaps: bool = True  # press the collider's limbs out of the rest of the body
    overlap_inset: float = 0.002  # m, how far inside the rest of the body a pressed limb stops
    self_friction: float = 0.2  # Coulomb friction between two layers of cloth
    # contact of the cloth with itself
    self_contact: bool = True  # resolve cloth-cloth contact
    self_contact_margin: float = 0.005  # m, distance kept between two layers of cloth
    self_contact_gap: float = 0.01  # m, extra reach of self-contact detection beyond the margin
    # m, cloth points closer than this in the rest shape never collide with each other
    self_contact_rest_exclusion: float = 0.0
    self_contact_passes: int = 2  # self-contact detections a substep: 2 (before and after), 1
    # timeline
    settle_seconds: float = 1.0  # drape under gravity on the rest pose before anything moves
    blend_seconds: float = 0.5  # the body blends from the rest pose into the motion's first frame
    settle_at_start: bool = True  # settle where the motion starts, not at the origin facing -Y
    settle_once: bool = False  # every clip starts from one rest drape, placed at its start
    # attachment and safety
    # m, the waistband is held this far outside the body along its normal; None: as placed
    waist_offset: float | None = 0.003
    jitter: float = 1.0e-4  # m, seeded random offset of the initial vertices: breaks symmetry
    max_distance: float = 10.0  # m, a vertex this far from the body's box stops the run
    # execution
    capture: bool = True  # replay recorded warp graphs for the substeps
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
