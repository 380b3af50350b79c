"""What the viewer paints on a garment: per-vertex values, their colour bins and bar.

Everything here is a pure function of arrays, one frame at a time (the viewer computes
a frame's values when it shows it):

* :func:`vertex_error`: each vertex's distance to the same vertex of a reference
  sequence (the simulation, say; the frame's RMSE is
  :func:`~loosefit.eval.metrics.rmse_per_frame`'s);
* :func:`vertex_strain`: ``|length / rest_length - 1|`` of the edges at each vertex
  (:func:`~loosefit.garment.quality.edge_strain`, the worst edge at the vertex);
* :func:`inside_depth`: how deep each vertex is inside the body, by the winding number
  on the posed body (:class:`~loosefit.geometry.query.Surface`, as
  :func:`~loosefit.eval.penetration.find_penetrations` decides it);
* :func:`face_bins` and :func:`split_by_bin`: the values as ``K`` colour bins of the
  faces (the browser draws one mesh per bin: viser's meshes take one colour each), and
  :func:`colour_bar_html`, the bar the panel shows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from loosefit.garment.quality import edge_strain
from loosefit.geometry.query import Surface
from loosefit.types import GarmentTemplate


@dataclass(frozen=True)
class ColourScale:
    """How a colour mode maps values to colours.

    Attributes:
        label: what the values are, for the colour bar.
        unit: the unit the bar's ticks are written in.
        factor: values (SI) times this are in ``unit``.
        vmax: the value (SI) at the top of the bar; 0 is at the bottom.
        colormap: a matplotlib colormap name.
    """

    label: str
    unit: str
    factor: float
    vmax: float
    colormap: str = "viridis"


# The modes the viewer offers, with their default ranges (each can be changed in the panel).
SCALES = {
    "error": ColourScale("distance to the reference", "cm", 100.0, 0.05, "viridis"),
    "strain": ColourScale("edge strain |l / l0 - 1|", "%", 100.0, 0.10, "magma"),
    "inside": ColourScale("depth inside the body", "mm", 1000.0, 0.01, "inferno"),
}


def vertex_error(vertices: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """(V,) m, each vertex's distance to the reference's same vertex.

    Args:
        vertices: (V, 3) a frame of a garment.
        reference: (V, 3) the same frame of the reference (the same garment).
    """
    return np.linalg.norm(np.asarray(vertices, np.float64) - reference, axis=-1)


def vertex_strain(vertices: np.ndarray, template: GarmentTemplate) -> np.ndarray:
    """(V,) the largest ``|length / rest_length - 1|`` of the edges at each vertex.

    The edges along the waistband are left out (the body sets their length), as in
    :func:`~loosefit.garment.quality.edge_strain`; a vertex with no other edge gets 0.

    Args:
        vertices: (V, 3) a frame of the garment.
        template: its rest shape.
    """
    strain, edges = edge_strain(np.asarray(vertices)[None], template)  # (1, E), (E, 2)
    out = np.zeros(len(vertices))
    np.maximum.at(out, edges[:, 0], strain[0])
    np.maximum.at(out, edges[:, 1], strain[0])
    return out


def inside_depth(surface: Surface, vertices: np.ndarray) -> np.ndarray:
    """(V,) m, how deep each vertex is inside the body (0 outside).

    Args:
        surface: the body, refitted to this frame's pose (built with ``winding_number``:
            inside by the generalised winding number, as the penetration diagnosis).
        vertices: (V, 3) the garment at this frame.
    """
    hit = surface.query(np.asarray(vertices, np.float32))
    return np.where(hit.inside & (hit.faces >= 0), hit.distance, 0.0)


def face_bins(faces: np.ndarray, values: np.ndarray, vmax: float, bins: int) -> np.ndarray:
    """(F,) int64 the colour bin of each face: its vertices' mean value in ``bins`` equal
    steps of ``[0, vmax]`` (values above ``vmax`` in the last).

    Args:
        faces: (F, 3) triangles.
        values: (V,) per-vertex values (>= 0).
        vmax: the top of the scale (> 0).
        bins: the number of bins K.
    """
    mean = np.asarray(values, np.float64)[faces].mean(1)  # (F,)
    return np.clip((mean / vmax * bins).astype(np.int64), 0, bins - 1)


def split_by_bin(faces: np.ndarray, bin_of_face: np.ndarray, bins: int) -> list[tuple]:
    """The faces of each bin as a mesh of its own: the vertices it uses and its triangles.

    Args:
        faces: (F, 3) triangles.
        bin_of_face: (F,) the bin of each face.
        bins: K.

    Returns:
        K pairs ``(used, local)``: ``used`` (n,) the vertex indices the bin's faces use,
        ``local`` (f, 3) uint32 its faces, indexing ``used``; both empty for an empty bin.
    """
    out = []
    for k in range(bins):
        f = faces[bin_of_face == k]  # (f, 3)
        used, local = np.unique(f, return_inverse=True)
        out.append((used, local.reshape(-1, 3).astype(np.uint32)))
    return out


def bin_colours(colormap: str, bins: int) -> np.ndarray:
    """(K, 3) uint8 the colour of each bin: the colormap sampled at the bins' centres."""
    from matplotlib import colormaps

    rgba = colormaps[colormap]((np.arange(bins) + 0.5) / bins)  # (K, 4)
    return (rgba[:, :3] * 255).round().astype(np.uint8)


def colour_bar_html(scale: ColourScale, vmax: float, bins: int) -> str:
    """The panel's colour bar: ``bins`` swatches from 0 to ``vmax`` with a tick at each end
    and the middle, in ``scale.unit``."""
    colours = bin_colours(scale.colormap, bins)
    cells = "".join(
        f'<div style="flex:1;background:rgb({r},{g},{b})"></div>' for r, g, b in colours
    )
    top = vmax * scale.factor
    ticks = "".join(f"<span>{v:.3g}</span>" for v in (0.0, top / 2, top))
    return (
        '<div style="font-size:0.8em;padding:0 0.5em">'
        f"<div>{scale.label} ({scale.unit})</div>"
        f'<div style="display:flex;height:0.9em;margin:0.2em 0">{cells}</div>'
        f'<div style="display:flex;justify-content:space-between">{ticks}</div>'
        "</div>"
    )
