"""Where a skirt hangs: the body's waist ellipse and the hips below it, from body vertices.

:func:`waist_fit_from_points` fits the waist ellipse to the vertices near a height, and
:func:`hip_profile_from_points` the ellipses that contain the body's cross-sections below
it (a :data:`HipProfile`); :class:`WaistFit` holds both for
:func:`~loosefit.garment.skirt.make_skirt`, and :func:`profile_radii` reads a profile at
given heights.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from loosefit.errors import LoosefitInputError

# A hip profile: rows (z, rx, ry), or a function z -> (rx, ry) (None where it does not apply).
HipProfile = np.ndarray | Sequence[Sequence[float]] | Callable[[float], tuple[float, float] | None]


@dataclass
class WaistFit:
    """The body's waist that a skirt's waistband must fit, and optionally its hips.

    Attributes:
        center: (3,) waist centre; the skirt's axis is the vertical line through its x, y.
        radii: (2,) semi-axes of the waist ellipse along X (wider) and Y (deeper), metres.
        height: z of the waistband.
        profile: the body below the waist, relative to ``center``'s x, y: rows
            ``(z, rx, ry)`` of ellipses containing the body's cross-section at
            height z (see :func:`hip_profile_from_points`), or a function
            ``z -> (rx, ry)`` returning None where it does not apply. Heights
            outside the rows' range are unconstrained. None: no hips.
    """

    center: np.ndarray
    radii: np.ndarray
    height: float
    profile: HipProfile | None = None

    def __post_init__(self) -> None:
        src = "WaistFit"
        self.center = np.asarray(self.center, dtype=np.float64)
        self.radii = np.asarray(self.radii, dtype=np.float64)
        if self.center.shape != (3,) or not np.isfinite(self.center).all():
            raise LoosefitInputError(src, "center", "3 finite numbers", repr(self.center))
        if self.radii.shape != (2,) or not (
            np.isfinite(self.radii).all() and (self.radii > 0).all()
        ):
            raise LoosefitInputError(src, "radii", "2 positive numbers", repr(self.radii))
        self.height = float(self.height)
        if not math.isfinite(self.height):
            raise LoosefitInputError(src, "height", "a finite number", repr(self.height))
        if self.profile is not None and not callable(self.profile):
            rows = np.asarray(self.profile, dtype=np.float64)
            if rows.ndim != 2 or rows.shape[1] != 3 or len(rows) < 1:
                raise LoosefitInputError(src, "profile", "rows (z, rx, ry)", f"shape {rows.shape}")
            if not np.isfinite(rows).all() or (rows[:, 1:] <= 0).any():
                raise LoosefitInputError(
                    src, "profile", "finite rows with positive radii", "NaN, inf or radius <= 0"
                )
            self.profile = rows[np.argsort(rows[:, 0])]


def _enclosing_ellipse(xy: np.ndarray) -> tuple[float, float]:
    """Semi-axes of the smallest centred, axis-aligned ellipse with the bounding box's aspect
    that contains every point (for an elliptical cross-section: its own semi-axes).

    Args:
        xy: (N, 2) points relative to the centre.
    """
    half = np.maximum(np.abs(xy).max(axis=0), 1e-6)  # (2,)
    scale = float(np.sqrt(((xy / half) ** 2).sum(axis=1)).max())
    return float(half[0] * scale), float(half[1] * scale)


def _drop_far(xy: np.ndarray, center: np.ndarray, max_radius: float | None) -> np.ndarray:
    """Mask of points within ``max_radius`` of ``center`` in XY (all when None)."""
    if max_radius is None:
        return np.ones(len(xy), dtype=bool)
    return np.linalg.norm(xy - center, axis=1) <= max_radius


def _check_points(source: str, points: np.ndarray) -> np.ndarray:
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise LoosefitInputError(source, "points", "shape (Vb, 3)", f"shape {points.shape}")
    if not np.isfinite(points).all():
        raise LoosefitInputError(source, "points", "finite coordinates", "NaN or inf")
    return points


def hip_profile_from_points(
    points: np.ndarray,
    z_top: float,
    z_bottom: float,
    n: int | None = None,
    *,
    center: np.ndarray | None = None,
    max_radius: float | None = None,
) -> np.ndarray:
    """The body's cross-sections between two heights, as ellipses the skirt must clear.

    Row k sits at ``z_k`` (``n`` heights evenly spaced from ``z_top`` down to
    ``z_bottom``) and summarises the points with ``|z - z_k| <= spacing``; its
    ellipse has the aspect of their bounding box about ``center`` and is just
    large enough to contain them all. Because neighbouring slabs overlap, the
    linearly interpolated ellipse at any height in between still contains the
    points there. Slabs without points are left out.

    Args:
        points: (Vb, 3) body vertices (torso and legs; leave out the arms, or set ``max_radius``).
        z_top: upper height, usually the waist's.
        z_bottom: lower height (< z_top).
        n: number of rows, >= 2; default: one per centimetre.
        center: (2,) or (3,) the skirt's axis; default: the middle of the points' XY bounding box.
        max_radius: ignore points farther than this from the axis in XY (e.g. hands at hip
            height in an A-pose).

    Returns:
        (K, 3) float64 rows (z, rx, ry), z descending, K <= n.
    """
    src = "hip_profile_from_points"
    points = _check_points(src, points)
    if not (z_bottom < z_top):
        raise LoosefitInputError(src, "z_bottom", f"a height below z_top = {z_top}", repr(z_bottom))
    if n is None:
        n = max(2, math.ceil((z_top - z_bottom) / 0.01) + 1)
    if n < 2:
        raise LoosefitInputError(src, "n", "at least 2 rows", repr(n))
    in_range = points[(points[:, 2] <= z_top) & (points[:, 2] >= z_bottom)]
    if len(in_range) == 0:
        raise LoosefitInputError(src, "points", f"points with z in [{z_bottom}, {z_top}]", "none")
    if center is None:
        center = 0.5 * (in_range[:, :2].min(0) + in_range[:, :2].max(0))
    center = np.asarray(center, dtype=np.float64)[:2]
    spacing = (z_top - z_bottom) / (n - 1)
    rows = []
    for z in np.linspace(z_top, z_bottom, n):
        slab = points[np.abs(points[:, 2] - z) <= spacing + 1e-12]
        xy = slab[:, :2] - center  # (N, 2)
        xy = xy[_drop_far(xy, np.zeros(2), max_radius)]
        if len(xy):
            rows.append((z, *_enclosing_ellipse(xy)))
    if not rows:
        raise LoosefitInputError(src, "points", "points within max_radius of the axis", "none")
    return np.asarray(rows, dtype=np.float64)


def waist_fit_from_points(
    points: np.ndarray,
    height: float,
    *,
    band: float = 0.015,
    max_radius: float | None = None,
    profile_depth: float = 0.0,
    profile_rows: int | None = None,
) -> WaistFit:
    """Fit the waist ellipse to body vertices near a height (and optionally the hips below).

    The centre is the middle of the XY bounding box of the vertices with
    ``|z - height| <= band``; the radii are those of the smallest ellipse with
    that box's aspect containing them (the box's half-extents for an
    elliptical waist).

    Args:
        points: (Vb, 3) body vertices.
        height: z of the waistband.
        band: half-thickness of the slab of vertices used, metres.
        max_radius: ignore vertices farther than this from the slab's median in XY (e.g.
            the arms).
        profile_depth: if > 0, also measure the hip profile from ``height`` down to
            ``height - profile_depth`` (see :func:`hip_profile_from_points`).
        profile_rows: number of rows of that profile; default: one per centimetre.

    Returns:
        The fitted :class:`WaistFit`.
    """
    src = "waist_fit_from_points"
    points = _check_points(src, points)
    slab = points[np.abs(points[:, 2] - height) <= band]
    if len(slab) < 8:
        raise LoosefitInputError(
            src, "points", f"at least 8 vertices within {band} m of z = {height}", str(len(slab))
        )
    xy = slab[:, :2]
    xy = xy[_drop_far(xy, np.median(xy, axis=0), max_radius)]
    if len(xy) < 8:
        raise LoosefitInputError(src, "max_radius", "a radius keeping 8 vertices", str(len(xy)))
    center_xy = 0.5 * (xy.min(0) + xy.max(0))
    radii = _enclosing_ellipse(xy - center_xy)
    center = np.array([center_xy[0], center_xy[1], height])
    profile = None
    if profile_depth > 0:
        profile = hip_profile_from_points(
            points,
            height,
            height - profile_depth,
            profile_rows,
            center=center_xy,
            max_radius=max_radius,
        )
    return WaistFit(center=center, radii=np.asarray(radii), height=height, profile=profile)


def profile_radii(profile: HipProfile | None, z: np.ndarray) -> np.ndarray:
    """Hip ellipse semi-axes at heights ``z``.

    Args:
        profile: see :class:`WaistFit`.
        z: (N,) heights.

    Returns:
        (N, 2) semi-axes, NaN where the profile does not apply.
    """
    out = np.full((len(z), 2), np.nan)
    if profile is None:
        return out
    if callable(profile):
        for k, zk in enumerate(z):
            value = profile(float(zk))
            if value is not None:
                out[k] = value
        return out
    rows = np.asarray(profile)  # (K, 3), z ascending
    for axis in (0, 1):
        out[:, axis] = np.interp(z, rows[:, 0], rows[:, 1 + axis], left=np.nan, right=np.nan)
    return out
