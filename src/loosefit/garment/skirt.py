"""Parametric skirts: a waistband fitted to the body, a hanging rest shape and a UV layout.

The mesh is a grid of ``rings x segments`` vertices: ring 0 is the waistband,
the last ring is the hem, and every ring starts at the back of the body (+Y,
the avatar faces -Y) and runs counter-clockwise seen from above. The grid is
cut open along the back seam, so the UV layout is a rectangle: u runs around
the body, v from the hem (v = margin, bottom of the UV square) up to the
waistband (v = 1 - margin, top), and each seam vertex has two UVs (u = margin
on one side, u = 1 - margin on the other). With u right and v up the layout
keeps the surface's orientation: UV triangles are counter-clockwise, and the 3D
triangles are counter-clockwise seen from outside (normals point away from the
body). Quad diagonals alternate like a checkerboard.

Rest shape. Every ring is the waist ellipse grown by an offset ``delta``
(semi-axes ``radii + waist_ease + delta``) and sampled at equal arc length.
Rings are built from the waist down so that each edge from one ring to the
next has exactly the pattern length ``length / (rings - 1)`` (the vertex's
height follows from its horizontal step). From ring to ring the offset grows
like a cone hanging at ``flare`` degrees from vertical, and more where the
body's hip profile (plus ``hip_ease``) would otherwise poke through: the skirt
hangs over the hips and continues at its flare angle below them.

* ``aline``: a gentle cone (default 10 degrees).
* ``flared``: a wide cone (default 30 degrees; with the default length the hem
  radius is about 2.5-3 times the waist radius).
* ``circle``: the flat pattern is an annulus whose inner circumference is the
  waistband's and whose width is ``length``, so its rings have circumference
  ``waist + 2 pi s`` at distance ``s`` from the waist: far more than a cone
  can hold. The rest shape is a cone (default 30 degrees) with ``flutes``
  sinusoidal folds along the ring's outward normal, whose amplitude is solved
  ring by ring so that each 3D ring is as long as the pattern's. Vertices are
  spaced evenly along each (wavy) 3D ring, so edges around a ring match the
  pattern's one by one (90 % of them within 4 % at the CPU resolution, 1 % at
  the paper's; the rest are chords across fold crests), and edges between
  rings match it exactly (the ring-to-ring construction above). Diagonals are
  within about 5 %. Fold crests hang higher than the troughs (about 8 cm at
  the hem with the defaults): the hem is wavy, as a real circle skirt's is
  before gravity settles it. ``meta['max_ring_error']`` and
  ``meta['max_edge_stretch']`` report what is left.

The rectangular UV unwrap is used for every style, the circle skirt included: it
fills the UV square (about 92 % of it with the default margin) where the
annulus of the flat pattern would fill about 70 % and leave the waist tiny.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from functools import partial

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.garment.waist_fit import HipProfile, WaistFit, profile_radii
from loosefit.types import GarmentTemplate

STYLES: tuple[str, ...] = ("aline", "flared", "circle")

# Hanging angle from vertical, degrees, when SkirtConfig.flare is None.
DEFAULT_FLARE_DEG: dict[str, float] = {"aline": 10.0, "flared": 30.0, "circle": 30.0}

# (rings, segments) per resolution and style; the vertex count is their product:
# cpu 2,304 / 2,352 / 2,288 and paper 9,344 / 9,352 / 9,328 (the paper's skirt has 9,352).
# Segments grow with the hem's width so that triangles stay roughly equilateral.
SKIRT_RESOLUTIONS: dict[str, dict[str, tuple[int, int]]] = {
    "cpu": {"aline": (32, 72), "flared": (28, 84), "circle": (22, 104)},
    "paper": {"aline": (64, 146), "flared": (56, 167), "circle": (44, 212)},
}


@dataclass
class SkirtConfig:
    """How a parametric skirt is shaped and meshed."""

    style: str = "aline"  # "aline", "flared" or "circle"
    length: float = 0.55  # metres from waistband to hem, measured along the fabric
    flare: float | None = None  # hanging angle from vertical, degrees; None: DEFAULT_FLARE_DEG
    rings: int = 32  # vertex rings from waistband (ring 0) to hem, >= 2
    segments: int = 72  # vertices around each ring, >= 8
    waist_ease: float = 0.01  # metres added to the waist semi-axes so the band sits outside
    hip_ease: float = 0.01  # metres the rest shape keeps outside the hip profile
    flutes: int = 10  # circle skirt only: number of folds around the hem
    uv_margin: float = 0.02  # UVs fill [uv_margin, 1 - uv_margin]^2

    def __post_init__(self) -> None:
        src = "SkirtConfig"
        if self.style not in STYLES:
            raise LoosefitInputError(src, "style", f"one of {STYLES}", repr(self.style))
        for name in ("length", "waist_ease", "hip_ease"):
            value = getattr(self, name)
            lowest = 0.0 if name != "length" else 1e-3
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= lowest):
                raise LoosefitInputError(src, name, f"a finite number >= {lowest}", repr(value))
        if self.flare is not None and not (0.0 <= self.flare < 89.0):
            raise LoosefitInputError(src, "flare", "an angle in [0, 89) degrees", repr(self.flare))
        if not (isinstance(self.rings, int) and self.rings >= 2):
            raise LoosefitInputError(src, "rings", "an integer >= 2", repr(self.rings))
        if not (isinstance(self.segments, int) and self.segments >= 8):
            raise LoosefitInputError(src, "segments", "an integer >= 8", repr(self.segments))
        if self.style == "circle" and not (
            isinstance(self.flutes, int) and 1 <= self.flutes <= self.segments // 6
        ):
            raise LoosefitInputError(
                src,
                "flutes",
                f"an integer in [1, segments // 6 = {self.segments // 6}]",
                repr(self.flutes),
                hint="each fold needs at least 6 vertices around the ring",
            )
        if not (0.0 <= self.uv_margin < 0.25):
            raise LoosefitInputError(
                src, "uv_margin", "a margin in [0, 0.25)", repr(self.uv_margin)
            )

    @property
    def flare_deg(self) -> float:
        """The hanging angle in degrees, the style's default when ``flare`` is None."""
        return DEFAULT_FLARE_DEG[self.style] if self.flare is None else float(self.flare)

    @property
    def num_vertices(self) -> int:
        return self.rings * self.segments

    @classmethod
    def preset(cls, resolution: str = "cpu", style: str = "aline", **overrides) -> SkirtConfig:
        """A config at a named resolution of :data:`SKIRT_RESOLUTIONS`.

        Args:
            resolution: "cpu" (about 2,300 vertices) or "paper" (about 9,350, as the paper's skirt).
            style: "aline", "flared" or "circle".
            **overrides: any other :class:`SkirtConfig` field.
        """
        if resolution not in SKIRT_RESOLUTIONS:
            raise LoosefitInputError(
                "SkirtConfig.preset",
                "resolution",
                f"one of {tuple(SKIRT_RESOLUTIONS)}",
                repr(resolution),
            )
        if style not in STYLES:
            raise LoosefitInputError("SkirtConfig.preset", "style", f"one of {STYLES}", repr(style))
        rings, segments = SKIRT_RESOLUTIONS[resolution][style]
        kwargs = {"style": style, "rings": rings, "segments": segments}
        kwargs.update(overrides)
        return cls(**kwargs)


# ---------------------------------------------------------------------------------------------
# Rest shape


@dataclass
class _RingSampler:
    """Builds rings on fluted offset ellipses, vertices equally spaced by 3D arc length."""

    segments: int  # S, vertices per ring
    flutes: int  # folds around the ring (0: a plain ellipse)
    dense: int = 4096  # M, points of the dense curve the vertices are sampled from
    refine: int = 3  # passes that respace vertices by 3D (not XY) length on wavy rings
    phi: np.ndarray = field(init=False)  # (M,) ellipse parameter, starting at the back (+Y)

    def __post_init__(self) -> None:
        self.phi = np.pi / 2 + np.linspace(0.0, 2 * np.pi, self.dense, endpoint=False)

    def curve(self, semi_axes: np.ndarray, amplitude: float) -> np.ndarray:
        """(M, 2) the ellipse ``semi_axes`` with ``flutes`` sinusoidal folds of ``amplitude``
        along its outward normal; the fold phase follows the ellipse's arc length."""
        ax, ay = semi_axes
        c, s = np.cos(self.phi), np.sin(self.phi)
        base = np.stack([ax * c, ay * s], axis=1)  # (M, 2)
        if amplitude > 0 and self.flutes > 0:
            normal = np.stack([ay * c, ax * s], axis=1)
            normal /= np.linalg.norm(normal, axis=1, keepdims=True)
            phase = 2 * np.pi * self.flutes * _arc_fraction(base)  # (M,)
            base = base + amplitude * np.sin(phase)[:, None] * normal
        return base

    def ring(
        self, semi_axes: np.ndarray, prev: np.ndarray, step: float, amplitude: float
    ) -> np.ndarray:
        """(S, 3) the next ring below ``prev`` (S, 3): see :meth:`curve` and :meth:`place`."""
        return self.place(self.curve(semi_axes, amplitude), prev, step)

    def place(self, curve: np.ndarray, prev: np.ndarray, step: float) -> np.ndarray:
        """(S, 3) ring vertices on ``curve`` (M, 2), each ``step`` from its vertex on ``prev``
        (S, 3) and spaced evenly by arc length along the (wavy) 3D ring."""
        xy, param = _resample_closed(curve, self.segments)
        z = _drop_to(prev, xy, step)
        for _ in range(self.refine if self.flutes > 0 else 0):
            z_dense = np.interp(np.arange(self.dense), param, z, period=self.dense)  # (M,)
            points, param = _resample_closed(np.column_stack([curve, z_dense]), self.segments)
            xy = points[:, :2]
            z = _drop_to(prev, xy, step)
        return np.column_stack([xy, z])


def _resample_closed(points: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Points evenly spaced by arc length along a closed polyline, from its first point.

    Args:
        points: (M, D) polyline vertices (closed: the last joins the first).
        count: N, number of samples.

    Returns:
        samples: (N, D) positions.
        param: (N,) their fractional vertex index along the polyline, in [0, M).
    """
    closed = np.vstack([points, points[:1]])  # (M + 1, D)
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))])
    targets = np.arange(count) / count * cum[-1]  # (N,)
    k = np.clip(np.searchsorted(cum, targets, side="right") - 1, 0, len(points) - 1)
    t = (targets - cum[k]) / np.maximum(cum[k + 1] - cum[k], 1e-15)
    return closed[k] + t[:, None] * (closed[k + 1] - closed[k]), k + t


def _arc_fraction(points: np.ndarray) -> np.ndarray:
    """(M,) fraction of a closed polyline's length from its first point to each point."""
    seg = np.linalg.norm(np.diff(np.vstack([points, points[:1]]), axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(seg)[:-1]]) / seg.sum()


def _closed_length(points: np.ndarray) -> float:
    """Length of the closed polyline through (N, D) points."""
    return float(np.linalg.norm(np.roll(points, -1, axis=0) - points, axis=1).sum())


def _drop_to(prev: np.ndarray, xy: np.ndarray, step: float) -> np.ndarray:
    """(S,) heights of ring points ``xy`` so that each lies ``step`` from ``prev`` (S, 3)."""
    horizontal2 = ((xy - prev[:, :2]) ** 2).sum(axis=1)
    return prev[:, 2] - np.sqrt(np.maximum(step**2 - horizontal2, 0.0))


def _clearance_deficit(ring: np.ndarray, profile: HipProfile | None, ease: float) -> float:
    """How far (metres, approximately) ring (S, 3) must move outward to clear the hips + ease."""
    radii = profile_radii(profile, ring[:, 2]) + ease  # (S, 2)
    ok = np.isfinite(radii).all(axis=1)
    if not ok.any():
        return 0.0
    xy = ring[ok, :2]
    scale = np.sqrt(((xy / radii[ok]) ** 2).sum(axis=1))  # < 1 inside the hip ellipse
    return float(((1.0 - scale) * np.linalg.norm(xy, axis=1)).max())


def rest_rings(config: SkirtConfig, waist: WaistFit) -> tuple[np.ndarray, dict]:
    """Ring positions relative to the skirt's axis, built from the waist down.

    Returns:
        rings: (R, S, 3) positions (x, y relative to the waist centre, z absolute).
        info: diagnostics for ``meta`` (offsets, fold amplitudes, pattern errors).
    """
    R, S = config.rings, config.segments
    step = config.length / (R - 1)  # pattern distance between rings
    slope = math.sin(math.radians(config.flare_deg))
    waist_axes = waist.radii + config.waist_ease  # (2,)
    circle = config.style == "circle"
    sampler = _RingSampler(S, config.flutes if circle else 0, dense=max(4096, 16 * S))

    rings = np.zeros((R, S, 3))
    rings[0, :, :2] = _resample_closed(sampler.curve(waist_axes, 0.0), S)[0]
    rings[0, :, 2] = waist.height
    # Circle pattern: an annulus with the waistband's circumference inside; its ring i is
    # a regular S-gon of radius r_in + i * step (the flat positions of the same vertices).
    r_in = _closed_length(sampler.curve(waist_axes, 0.0)) / (2 * np.pi)
    pattern = 2 * S * (r_in + step * np.arange(R)) * np.sin(np.pi / S)  # (R,) ring lengths

    offsets, amplitudes = np.zeros(R), np.zeros(R)
    for i in range(1, R):
        prev = rings[i - 1]
        offset = offsets[i - 1] + step * slope

        for _ in range(50):  # push the ring out until it clears the hips (+ ease)
            axes = waist_axes + offset
            build = partial(sampler.ring, axes, prev, step)  # amplitude -> (S, 3) ring
            amplitude = 0.0
            if circle:  # folds deeper than the ellipse's tightest curvature radius would cross
                cap = 0.8 * axes.min() ** 2 / axes.max()
                amplitude = _solve_amplitude(build, pattern[i], cap)
            ring = build(amplitude)
            deficit = _clearance_deficit(ring, waist.profile, config.hip_ease)
            if deficit <= 0:
                break
            offset += deficit + 1e-4
        rings[i], offsets[i], amplitudes[i] = ring, offset, amplitude

    edges_down = np.linalg.norm(np.diff(rings, axis=0), axis=2)  # (R - 1, S)
    ring_lengths = np.array([_closed_length(r) for r in rings])
    info = {
        "ring_offsets": offsets.tolist(),
        "max_edge_stretch": float(np.abs(edges_down / step - 1).max()),
    }
    if circle:
        info.update(
            pattern_inner_radius=float(r_in),
            pattern_outer_radius=float(r_in + config.length),
            fold_amplitudes=amplitudes.tolist(),
            max_ring_error=float(np.abs(ring_lengths / pattern - 1).max()),
        )
    return rings, info


def _solve_amplitude(build: Callable[[float], np.ndarray], target: float, upper: float) -> float:
    """Fold amplitude in [0, upper] whose ring (built by ``build``) has length ``target``.

    Regula falsi with the Illinois step on the bracket [0, upper]; the ring length grows
    smoothly with the amplitude, so a handful of rings are built.
    """

    def error(amplitude: float) -> float:
        return _closed_length(build(amplitude)) - target

    lo, hi = 0.0, upper
    f_lo, f_hi = error(lo), error(hi)
    if f_lo >= 0:
        return lo
    if f_hi <= 0:
        return hi
    side = 0
    for _ in range(60):
        mid = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        f_mid = error(mid)
        if abs(f_mid) <= 1e-7 * target:
            return mid
        if f_mid < 0:
            lo, f_lo = mid, f_mid
            if side == -1:
                f_hi *= 0.5
            side = -1
        else:
            hi, f_hi = mid, f_mid
            if side == 1:
                f_lo *= 0.5
            side = 1
    return mid


# ---------------------------------------------------------------------------------------------
# Topology and UVs


def skirt_grid(
    rings: int, segments: int, margin: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Faces and UVs of a ``rings x segments`` tube cut open at the seam (column 0).

    Vertex ``i * segments + j`` is ring i, column j; UV ``i * (segments + 1) + j``
    is its UV, with column ``segments`` repeating column 0 at u = 1 - margin.

    Args:
        rings: R, number of rings (ring 0 at the top, v = 1 - margin).
        segments: S, vertices around a ring.
        margin: UVs fill [margin, 1 - margin]^2.

    Returns:
        faces: (2 (R - 1) S, 3) int64 vertex indices.
        face_uvs: (2 (R - 1) S, 3) int64 UV indices.
        uvs: (R (S + 1), 2) float64 UVs.
    """
    R, S = rings, segments
    i = np.arange(R - 1)[:, None]  # (R - 1, 1)
    j = np.arange(S)[None, :]  # (1, S)
    even = ((i + j) % 2 == 0)[..., None]  # (R - 1, S, 1): which diagonal each quad uses

    def triangles(stride: int, right: np.ndarray) -> np.ndarray:
        a, b = i * stride + j, i * stride + right  # top-left, top-right
        c, d = a + stride, b + stride  # bottom-left, bottom-right
        a, b, c, d = np.broadcast_arrays(a, b, c, d)
        first = np.where(even, np.stack([c, d, b], -1), np.stack([c, d, a], -1))  # (R-1, S, 3)
        second = np.where(even, np.stack([c, b, a], -1), np.stack([d, b, a], -1))
        return np.stack([first, second], axis=2).reshape(-1, 3)  # (2 (R - 1) S, 3)

    faces = triangles(S, (j + 1) % S)
    face_uvs = triangles(S + 1, j + 1)
    u = margin + (1 - 2 * margin) * np.arange(S + 1) / S
    v = 1 - margin - (1 - 2 * margin) * np.arange(R) / (R - 1)
    uu, vv = np.meshgrid(u, v)  # (R, S + 1)
    uvs = np.stack([uu, vv], axis=-1).reshape(-1, 2)
    return faces.astype(np.int64), face_uvs.astype(np.int64), uvs


def make_skirt(config: SkirtConfig, waist: WaistFit) -> GarmentTemplate:
    """Build a skirt whose waistband fits ``waist`` and whose rest shape hangs clear of the hips.

    Args:
        config: style, length and resolution.
        waist: the body's waist (and optionally its hip profile).

    Returns:
        A :class:`GarmentTemplate` with V = rings * segments vertices,
        F = 2 (rings - 1) segments faces, U = rings * (segments + 1) UVs, the
        waistband = ring 0 (vertices 0..segments-1), ``meta`` holding the
        config, the waist fit and the rest-shape diagnostics.
    """
    rings, info = rest_rings(config, waist)  # (R, S, 3)
    rings[..., :2] += waist.center[:2]
    faces, face_uvs, uvs = skirt_grid(config.rings, config.segments, config.uv_margin)
    meta = {
        "style": config.style,
        "config": asdict(config),
        "waist_fit": {
            "center": waist.center.tolist(),
            "radii": waist.radii.tolist(),
            "height": waist.height,
            "has_profile": waist.profile is not None,
        },
        "flare_deg": config.flare_deg,
        "uv_layout": "rectangle, u around from the back seam, v = 1 - margin at the waist",
        **info,
    }
    return GarmentTemplate(
        vertices=rings.reshape(-1, 3),  # (V, 3)
        faces=faces,
        uvs=uvs,
        face_uvs=face_uvs,
        waist=np.arange(config.segments),
        name=f"skirt_{config.style}",
        meta=meta,
    )
