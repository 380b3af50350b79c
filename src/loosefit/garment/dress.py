"""A parametric dress: a bodice from the chest down that flares into a skirt, strapless or
with two shoulder straps, with a UV layout.

The body of the dress is built like a skirt (:mod:`loosefit.garment.skirt`), from its top
band down: ring 0 is the top band fitted round the chest under the arms, every ring is
the band's ellipse grown as a cone hanging at ``flare`` degrees and pushed out wherever
the body (bust, belly, hips) would poke through, so the dress falls from the bust as an
empire line does and continues as an A-line skirt. Rings start at the back (+Y) and run
counter-clockwise seen from above; the tube is cut open at the back seam for its UVs.

``straps``: two strips of ``strap_columns`` vertices across, from the top band's front
over each shoulder to its back, shaped as a half ellipse and pushed off the body by the
caller's ``push_out`` (so that they rest on the shoulders). They share the top band's
vertices where they join it, so the dress is one manifold piece whose openings are the
neckline, two armholes and the hem.

What the simulation holds (the template's ``waist``, ``meta["attachment"]``): the top band
for a strapless dress (``"loop"``, glued round the chest like a skirt's waistband), the
straps' vertices over the shoulders for a dress with straps (``"points"``).

UVs: the body of the dress fills the top of the UV square (v from 0.2 to 1 - margin, u
round from the back seam), each strap a strip along the bottom (one per half of u).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.garment.skirt import SkirtConfig, rest_rings, skirt_grid
from loosefit.garment.waist_fit import WaistFit
from loosefit.types import GarmentTemplate

DRESS_STYLES = ("strapless", "straps")
# the names the commands take for the parametric dress: its style
DRESS_SPECS = {"dress": "straps", **{f"dress-{s}": s for s in DRESS_STYLES}}

# (rings, segments, strap rows, strap columns) per resolution: cpu 2,312 + 60 strap
# vertices = 2,372, paper 9,248 + 220 = 9,468 (the paper's skirt has 9,352)
DRESS_RESOLUTIONS: dict[str, tuple[int, int, int, int]] = {
    "cpu": (34, 68, 12, 3),
    "paper": (68, 136, 24, 5),
}
BODY_UV_BOTTOM = 0.2  # the dress's body fills v in [BODY_UV_BOTTOM, 1 - margin]


@dataclass
class DressConfig:
    """How a parametric dress is shaped and meshed."""

    style: str = "straps"  # "straps" or "strapless"
    length: float = 0.8  # metres of fabric from the top band to the hem (below the knee)
    flare: float = 14.0  # hanging angle of the skirt part from vertical, degrees
    rings: int = 34  # vertex rings from the top band (ring 0) to the hem, >= 2
    segments: int = 68  # vertices round each ring, >= 8
    top_ease: float = 0.012  # metres added to the chest's semi-axes at the top band
    body_ease: float = 0.015  # metres the rest shape keeps outside the bust, belly and hips
    strap_rows: int = 12  # vertices along a strap, its two ends on the top band included
    strap_columns: int = 3  # vertices across a strap (top band vertices it spans)
    uv_margin: float = 0.02  # the UV layout's gap to the edges of the UV square

    def __post_init__(self) -> None:
        src = "DressConfig"
        if self.style not in DRESS_STYLES:
            raise LoosefitInputError(src, "style", f"one of {DRESS_STYLES}", repr(self.style))
        for name in ("length", "top_ease", "body_ease"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
                raise LoosefitInputError(src, name, "a finite number >= 0", repr(value))
        if self.length < 0.2:
            raise LoosefitInputError(src, "length", "at least 0.2 m", repr(self.length))
        if not 0.0 <= self.flare < 80.0:
            raise LoosefitInputError(src, "flare", "an angle in [0, 80) degrees", repr(self.flare))
        for name, low in (("rings", 2), ("segments", 8), ("strap_rows", 3), ("strap_columns", 2)):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= low):
                raise LoosefitInputError(src, name, f"an integer >= {low}", repr(value))

    @classmethod
    def preset(cls, resolution: str = "cpu", style: str = "straps", **overrides) -> DressConfig:
        """A config at a named resolution of :data:`DRESS_RESOLUTIONS` ("cpu" or "paper")."""
        if resolution not in DRESS_RESOLUTIONS:
            raise LoosefitInputError(
                "DressConfig.preset",
                "resolution",
                f"one of {tuple(DRESS_RESOLUTIONS)}",
                repr(resolution),
            )
        rings, segments, rows, columns = DRESS_RESOLUTIONS[resolution]
        kwargs = dict(
            style=style, rings=rings, segments=segments, strap_rows=rows, strap_columns=columns
        )
        kwargs.update(overrides)
        return cls(**kwargs)


@dataclass
class DressFit:
    """The body a dress is made for (the avatar's rest frame).

    Attributes:
        top: the chest under the arms, where the top band goes: a :class:`WaistFit` whose
            ``profile`` holds the body's cross-sections below it (bust, belly, hips).
        strap_x: distance of each strap's middle from the body's axis (m).
        strap_top: height each strap reaches over the shoulder (m).
        push_out: (N, 3) -> (N, 3): points moved out of the body to a small clearance
            (identity where they are already clear); None leaves the straps as built.
    """

    top: WaistFit
    strap_x: float
    strap_top: float
    push_out: Callable[[np.ndarray], np.ndarray] | None = None


def _strap(
    ring: np.ndarray, columns: int, side: float, fit: DressFit, rows: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One strap: the front and back top-band columns it starts and ends on, and the
    positions of its inner rows.

    Returns:
        front: (C,) and back: (C,) top-band vertex indices, by increasing x;
        inner: (rows - 2, C, 3) positions between them.
    """
    centre = fit.top.center[:2]
    x = ring[:, 0] - centre[0]
    S = len(ring)
    ends = []
    for front in (True, False):
        on_side = (ring[:, 1] < centre[1]) if front else (ring[:, 1] > centre[1])
        best, best_cost = None, np.inf
        for start in range(S):
            cols = (start + np.arange(columns)) % S
            if not on_side[cols].all():
                continue
            cost = abs(x[cols].mean() - side * fit.strap_x)
            if cost < best_cost:
                best, best_cost = cols, cost
        if best is None:
            raise LoosefitInputError(
                "DressConfig", "strap_columns", "fewer columns than a side of the top band", columns
            )
        ends.append(best[np.argsort(x[best])])
    front, back = ends
    F, B = ring[front], ring[back]  # (C, 3) each
    theta = np.linspace(0.0, np.pi, rows)[1:-1, None, None]  # (rows - 2, 1, 1)
    mid = 0.5 * (F + B)
    half = 0.5 * (B - F)
    lift = fit.strap_top - 0.5 * (F[:, 2] + B[:, 2])  # (C,)
    inner = mid - np.cos(theta) * half  # (rows - 2, C, 3): front to back along y (and x)
    inner[..., 2] = (
        F[:, 2]
        + (B[:, 2] - F[:, 2]) * (1 - np.cos(theta[..., 0])) / 2
        + lift * np.sin(theta[..., 0])
    )
    if fit.push_out is not None:
        inner = fit.push_out(inner.reshape(-1, 3)).reshape(inner.shape)
    return front, back, inner


def make_dress(config: DressConfig, fit: DressFit) -> GarmentTemplate:
    """Build a dress whose top band fits ``fit.top`` and whose rest shape clears the body.

    Returns:
        A :class:`GarmentTemplate` (the avatar's rest frame): ``rings * segments`` body
        vertices, then the straps' inner rows; ``waist`` the attachment (see the module);
        ``meta`` the config, the fit, and ``kind: "dress"``.
    """
    R, S = config.rings, config.segments
    skirt_like = SkirtConfig(
        style="aline",
        length=config.length,
        flare=config.flare,
        rings=R,
        segments=S,
        waist_ease=config.top_ease,
        hip_ease=config.body_ease,
        uv_margin=config.uv_margin,
    )
    rings, info = rest_rings(skirt_like, fit.top)  # (R, S, 3), x, y about the centre
    rings[..., :2] += fit.top.center[:2]
    vertices = [rings.reshape(-1, 3)]
    faces, face_uvs, uvs = skirt_grid(R, S, config.uv_margin)
    m = config.uv_margin
    uvs = uvs.copy()
    uvs[:, 1] = BODY_UV_BOTTOM + (uvs[:, 1] - m) / (1 - 2 * m) * (1 - m - BODY_UV_BOTTOM)
    faces, face_uvs, uvs = [faces], [face_uvs], [uvs]
    attach = np.arange(S)
    strap_ids = []
    if config.style == "straps":
        n_v, n_uv = R * S, len(uvs[0])
        rows, C = config.strap_rows, config.strap_columns
        for k, side in enumerate((-1.0, 1.0)):  # the avatar's right (-X), then left
            front, back, inner = _strap(rings[0], C, side, fit, rows)
            ids = np.vstack([front, n_v + np.arange((rows - 2) * C).reshape(rows - 2, C), back])
            vertices.append(inner.reshape(-1, 3))
            n_v += (rows - 2) * C
            r, c = np.meshgrid(np.arange(rows - 1), np.arange(C - 1), indexing="ij")
            a, b, cc, d = ids[r, c], ids[r, c + 1], ids[r + 1, c], ids[r + 1, c + 1]
            tri = np.concatenate(
                [np.stack([a, cc, d], -1).reshape(-1, 3), np.stack([a, d, b], -1).reshape(-1, 3)]
            )
            # the strap's edge along the top band runs against the bodice's there
            body_edges = {
                (int(f[i]), int(f[(i + 1) % 3]))
                for f in faces[0]
                for i in range(3)
                if f[i] in front and f[(i + 1) % 3] in front
            }
            strap_edges = {(int(f[i]), int(f[(i + 1) % 3])) for f in tri for i in range(3)}
            flip = bool(body_edges & strap_edges)
            faces.append(tri[:, ::-1] if flip else tri)
            uid = n_uv + np.arange(rows * C).reshape(rows, C)
            u0 = m + 0.5 * k
            u = u0 + (0.5 - 2 * m) * np.arange(rows) / (rows - 1)
            v = m + (BODY_UV_BOTTOM - 2 * m - 0.02) * np.arange(C) / (C - 1)
            uu, vv = np.meshgrid(u, v, indexing="ij")
            uvs.append(np.stack([uu, vv], -1).reshape(-1, 2))
            n_uv += rows * C
            ua, ub, uc, ud = uid[r, c], uid[r, c + 1], uid[r + 1, c], uid[r + 1, c + 1]
            ftri = np.concatenate(
                [
                    np.stack([ua, uc, ud], -1).reshape(-1, 3),
                    np.stack([ua, ud, ub], -1).reshape(-1, 3),
                ]
            )
            ftri = ftri[:, ::-1] if flip else ftri
            chart = uvs[-1]
            e1, e2 = (
                chart[ftri[:, 1] - n_uv + rows * C] - chart[ftri[:, 0] - n_uv + rows * C],
                chart[ftri[:, 2] - n_uv + rows * C] - chart[ftri[:, 0] - n_uv + rows * C],
            )
            if (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum() < 0:  # keep UVs counter-clockwise
                chart[:, 1] = chart[:, 1].min() + chart[:, 1].max() - chart[:, 1]
            face_uvs.append(ftri)
            strap_ids.append(ids)
        # held over the shoulders: the middle third of each strap
        lo, hi = rows // 3, rows - rows // 3
        attach = np.concatenate([ids[lo:hi].ravel() for ids in strap_ids])
    meta = {
        "kind": "dress",
        "style": config.style,
        "config": asdict(config),
        "attachment": "points" if config.style == "straps" else "loop",
        "top_fit": {
            "center": fit.top.center.tolist(),
            "radii": fit.top.radii.tolist(),
            "height": fit.top.height,
        },
        "strap_x": fit.strap_x,
        "strap_top": fit.strap_top,
        "uv_layout": f"body: v in [{BODY_UV_BOTTOM}, 1 - margin] round from the back seam; "
        "straps: strips along the bottom",
        **info,
    }
    return GarmentTemplate(
        vertices=np.concatenate(vertices).astype(np.float32),
        faces=np.concatenate(faces).astype(np.int64),
        uvs=np.concatenate(uvs).astype(np.float32),
        face_uvs=np.concatenate(face_uvs).astype(np.int64),
        waist=np.asarray(attach, np.int64),
        name=f"dress_{config.style}",
        meta=meta,
    )
