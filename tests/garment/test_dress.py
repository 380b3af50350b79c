"""The parametric dress on a plain elliptic chest: its vertex counts, its attachment, its
straps wound as the bodice, and the refusals of its configuration."""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.garment.dress import DressConfig, DressFit, make_dress
from loosefit.garment.mesh_checks import boundary_loops, degenerate_faces, nonmanifold_edges
from loosefit.garment.skirt import WaistFit

FIT = DressFit(
    top=WaistFit(center=[0.0, 0.0, 1.3], radii=[0.15, 0.11], height=1.3),
    strap_x=0.08,
    strap_top=1.5,
)


def _directed_edges(faces: np.ndarray) -> np.ndarray:
    return np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])


def test_a_strapless_dress_is_a_tube_held_by_its_top_band():
    config = DressConfig(style="strapless", rings=10, segments=24, length=0.5)
    dress = make_dress(config, FIT)
    assert dress.num_vertices == 10 * 24 and dress.name == "dress_strapless"
    np.testing.assert_array_equal(dress.waist, np.arange(24))  # ring 0, the top band
    np.testing.assert_allclose(dress.vertices[:24, 2], 1.3, atol=1e-6)
    assert dress.meta["kind"] == "dress" and dress.meta["attachment"] == "loop"
    assert len(boundary_loops(dress.faces)) == 2  # the top band and the hem
    assert dress.vertices[:, 2].min() < 1.3 - 0.4  # hangs about its length below the band


@pytest.mark.parametrize(("resolution", "count"), [("cpu", 2372), ("paper", 9468)])
def test_the_named_resolutions_have_their_vertex_counts(resolution, count):
    dress = make_dress(DressConfig.preset(resolution), FIT)
    assert dress.num_vertices == count
    assert len(degenerate_faces(dress.vertices, dress.faces)) == 0
    assert nonmanifold_edges(dress.faces).shape == (0, 2)


def test_straps_are_held_over_the_shoulders_and_wound_as_the_bodice():
    config = DressConfig(rings=10, segments=24, length=0.5, strap_rows=9, strap_columns=3)
    dress = make_dress(config, FIT)
    R, S, rows, C = 10, 24, 9, 3
    assert dress.num_vertices == R * S + 2 * (rows - 2) * C
    assert dress.meta["attachment"] == "points" and dress.name == "dress_straps"
    # the middle third of each strap's rows, every column: all strap vertices of their own
    lo, hi = rows // 3, rows - rows // 3
    assert len(dress.waist) == 2 * (hi - lo) * C and (dress.waist >= R * S).all()
    held = dress.vertices[dress.waist]
    assert (held[:, 2] > 1.3).all()  # above the top band, over the shoulders
    assert (held[:, 0] < 0).any() and (held[:, 0] > 0).any()  # one strap on each side
    # one orientation over the whole surface: no edge is run twice the same way
    directed = _directed_edges(dress.faces)
    assert len(np.unique(directed, axis=0)) == len(directed)
    assert len(boundary_loops(dress.faces)) > 2  # the hem, the necklines, the armholes
    # UVs counter-clockwise on every face: the texture is not mirrored anywhere
    tri = dress.uvs[dress.face_uvs].astype(np.float64)
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    assert (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] > 0).all()


@pytest.mark.parametrize(
    ("field", "value", "expected"),
    [
        ("style", "gown", "one of"),
        ("length", 0.1, "at least 0.2 m"),
        ("length", float("nan"), "a finite number >= 0"),
        ("flare", 85.0, r"an angle in \[0, 80\) degrees"),
        ("rings", 1, "an integer >= 2"),
        ("segments", 8.0, "an integer >= 8"),
        ("strap_columns", 1, "an integer >= 2"),
    ],
)
def test_bad_configurations_are_refused_naming_the_field(field, value, expected):
    with pytest.raises(
        LoosefitInputError, match=rf"DressConfig: field '{field}': expected {expected}"
    ):
        DressConfig(**{field: value})


def test_an_unknown_resolution_is_refused():
    with pytest.raises(LoosefitInputError, match=r"DressConfig.preset: field 'resolution'.*'huge'"):
        DressConfig.preset("huge")
    assert DressConfig.preset("cpu", "strapless", length=0.6).length == 0.6
