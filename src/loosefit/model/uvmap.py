"""Per-vertex values to a UV-space image and back (paper 3.2).

The garment's UV layout is rasterised once: every texel of an ``H x W`` map
holds a triangle of the layout and barycentric weights, so that

* :meth:`UVMap.encode` turns per-vertex values ``(B, V, C)`` into maps
  ``(B, C, H, W)`` by barycentric interpolation inside each UV triangle, and
* :meth:`UVMap.sample` reads maps back at each vertex's UV coordinates with
  bilinear interpolation (differentiable); a vertex on a UV seam, with several
  UV coordinates, gets the mean of its samples.

Texels that no triangle covers take the triangle of the nearest covered texel
(weights clipped to it), so the map is continuous across the layout's border
and bilinear sampling at a border vertex reads sensible values; ``mask`` marks
the covered texels. Image rows follow v and columns u: texel ``(row, col)`` has
its centre at ``u = (col + 0.5) / W``, ``v = (row + 0.5) / H``, the convention
of ``torch.nn.functional.grid_sample`` with ``align_corners=False``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F
from scipy import ndimage

from loosefit.errors import LoosefitInputError
from loosefit.types import GarmentTemplate


@dataclass
class Rasterized:
    """A rasterised UV layout (see :func:`rasterize_uv`).

    Attributes:
        faces: (H, W) int64 triangle of each texel (covered or nearest covered).
        barycentric: (H, W, 3) float32 weights of the texel centre in that triangle.
        covered: (H, W) bool, the texel centre lies inside a triangle.
    """

    faces: np.ndarray
    barycentric: np.ndarray
    covered: np.ndarray


def _barycentric(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """(N, 3) barycentric coordinates of points p (N, 2) in the 2D triangle (a, b, c)."""
    v0, v1, v2 = b - a, c - a, p - a
    den = v0[0] * v1[1] - v1[0] * v0[1]
    w1 = (v2[:, 0] * v1[1] - v1[0] * v2[:, 1]) / den
    w2 = (v0[0] * v2[:, 1] - v2[:, 0] * v0[1]) / den
    return np.stack([1.0 - w1 - w2, w1, w2], axis=-1)


def rasterize_uv(uvs: np.ndarray, face_uvs: np.ndarray, size: int, source: str = "uv layout"):
    """Rasterise a UV layout into a ``size x size`` grid of texels.

    Args:
        uvs: (U, 2) UV coordinates in the unit square.
        face_uvs: (F, 3) indices into ``uvs`` per triangle corner.
        size: texels per side.
        source: names the layout in errors.

    Returns:
        A :class:`Rasterized`.

    Raises:
        LoosefitInputError: UVs outside the unit square, a degenerate UV
            triangle, or two triangles overlapping in UV space.
    """
    uvs = np.asarray(uvs, np.float64)
    face_uvs = np.asarray(face_uvs, np.int64)
    outside = ~np.isfinite(uvs).all(1) | (uvs < -1e-6).any(1) | (uvs > 1 + 1e-6).any(1)
    if outside.any():
        bad = int(np.nonzero(outside)[0][0])
        raise LoosefitInputError(
            source, "uvs", "coordinates in [0, 1]", f"uvs[{bad}] = {uvs[bad].tolist()}"
        )
    tri = uvs[face_uvs]  # (F, 3, 2)
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    area = 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    if (np.abs(area) < 1e-12).any():
        bad = int(np.nonzero(np.abs(area) < 1e-12)[0][0])
        raise LoosefitInputError(source, "face_uvs", "UV triangles of non-zero area", f"face {bad}")
    n = size
    owner = np.full((n, n), -1, np.int64)
    bary = np.zeros((n, n, 3), np.float64)
    eps = 1e-7
    for f in range(len(tri)):
        lo = np.floor(tri[f].min(0) * n - 0.5).astype(int)
        hi = np.ceil(tri[f].max(0) * n - 0.5).astype(int)
        cols = np.arange(max(lo[0], 0), min(hi[0], n - 1) + 1)
        rows = np.arange(max(lo[1], 0), min(hi[1], n - 1) + 1)
        if len(cols) == 0 or len(rows) == 0:
            continue
        rr, cc = np.meshgrid(rows, cols, indexing="ij")
        p = np.stack([(cc.ravel() + 0.5) / n, (rr.ravel() + 0.5) / n], -1)
        w = _barycentric(p, tri[f, 0], tri[f, 1], tri[f, 2])
        inside = (w >= -eps).all(1)
        if not inside.any():
            continue
        r, c = rr.ravel()[inside], cc.ravel()[inside]
        strict = (w[inside] > 1e-4).all(1)
        clash = (owner[r, c] >= 0) & strict
        if clash.any():
            k = int(np.nonzero(clash)[0][0])
            other = int(owner[r[k], c[k]])
            # a texel strictly inside this triangle that another triangle already holds
            w_other = _barycentric(p[inside][k : k + 1], *tri[other])[0]
            if (w_other > 1e-4).all():
                raise LoosefitInputError(
                    source,
                    "face_uvs",
                    "non-overlapping UV triangles",
                    f"faces {other} and {f} overlap at uv {p[inside][k].round(4).tolist()}",
                    hint="give every triangle its own place in the UV square (e.g. xatlas)",
                )
        owner[r, c] = f
        bary[r, c] = w[inside]
    covered = owner >= 0
    if not covered.any():
        want = f"triangles covering texels of a {n}x{n} map"
        raise LoosefitInputError(source, "uvs", want, "none")
    # Uncovered texels: the nearest covered texel's triangle, weights clipped to it.
    _, (ri, ci) = ndimage.distance_transform_edt(~covered, return_indices=True)
    faces = owner[ri, ci]
    rr, cc = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    out = ~covered
    if out.any():
        p = np.stack([(cc[out] + 0.5) / n, (rr[out] + 0.5) / n], -1)
        t = tri[faces[out]]  # (N, 3, 2)
        v0, v1, v2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0], p - t[:, 0]
        den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
        w1 = (v2[:, 0] * v1[:, 1] - v1[:, 0] * v2[:, 1]) / den
        w2 = (v0[:, 0] * v2[:, 1] - v2[:, 0] * v0[:, 1]) / den
        w = np.clip(np.stack([1.0 - w1 - w2, w1, w2], -1), 0.0, None)
        bary[out] = w / w.sum(-1, keepdims=True)
    return Rasterized(faces=faces, barycentric=bary.astype(np.float32), covered=covered)


class UVMap(torch.nn.Module):
    """A garment's UV layout as an image grid: per-vertex values to maps and back.

    Args:
        template: the garment (its ``faces``, ``uvs`` and ``face_uvs``).
        size: texels per side (H = W = size).
    """

    def __init__(self, template: GarmentTemplate, size: int) -> None:
        super().__init__()
        if not (isinstance(size, int) and size >= 4):
            raise LoosefitInputError("UVMap", "size", "an integer >= 4", repr(size))
        self.size = size
        self.num_vertices = template.num_vertices
        r = rasterize_uv(template.uvs, template.face_uvs, size, f"garment '{template.name}'")
        corners = template.faces[r.faces.ravel()]  # (H*W, 3) vertex indices
        self.register_buffer("texel_vertices", torch.from_numpy(corners), persistent=False)
        self.register_buffer(
            "texel_weights", torch.from_numpy(r.barycentric.reshape(-1, 3)), persistent=False
        )
        self.register_buffer("mask", torch.from_numpy(r.covered), persistent=False)
        # One sample per distinct (vertex, uv) pair of the face corners.
        pairs = np.unique(np.stack([template.faces.ravel(), template.face_uvs.ravel()], 1), axis=0)
        uv = template.uvs[pairs[:, 1]].astype(np.float32)
        grid = torch.from_numpy(2.0 * uv - 1.0).view(1, 1, -1, 2)  # x = u, y = v
        count = np.bincount(pairs[:, 0], minlength=self.num_vertices).astype(np.float32)
        if (count == 0).any():
            bad = int(np.nonzero(count == 0)[0][0])
            raise LoosefitInputError(
                f"garment '{template.name}'",
                "faces",
                "every vertex in a triangle",
                f"vertex {bad} in none",
            )
        self.register_buffer("sample_grid", grid, persistent=False)
        self.register_buffer("sample_vertex", torch.from_numpy(pairs[:, 0]), persistent=False)
        self.register_buffer("sample_count", torch.from_numpy(count), persistent=False)

    def encode(self, values: torch.Tensor) -> torch.Tensor:
        """Per-vertex values (B, V, C) to UV maps (B, C, H, W)."""
        B, V, C = values.shape
        if V != self.num_vertices:
            raise LoosefitInputError(
                "UVMap.encode", "values", f"(B, {self.num_vertices}, C)", f"{tuple(values.shape)}"
            )
        corner = values[:, self.texel_vertices]  # (B, HW, 3, C)
        texels = (corner * self.texel_weights[None, :, :, None]).sum(2)  # (B, HW, C)
        return texels.transpose(1, 2).reshape(B, C, self.size, self.size)

    def sample(self, maps: torch.Tensor) -> torch.Tensor:
        """UV maps (B, C, H, W) read back at the vertices: (B, V, C), bilinear."""
        B, C = maps.shape[:2]
        # Sampled in float32 even under a bf16 autocast: a map of absolute positions (the
        # vertex decoder's) would otherwise round to millimetres.
        maps = maps.double() if maps.dtype == torch.float64 else maps.float()
        with torch.autocast(maps.device.type, enabled=False):
            grid = self.sample_grid.to(maps.dtype).expand(B, -1, -1, -1)
            s = F.grid_sample(
                maps, grid, mode="bilinear", padding_mode="border", align_corners=False
            )
        s = s[:, :, 0].transpose(1, 2)  # (B, N, C)
        out = torch.zeros(B, self.num_vertices, C, dtype=s.dtype, device=s.device)
        out.index_add_(1, self.sample_vertex, s)
        return out / self.sample_count.to(s.dtype)[None, :, None]
