"""Parametric skirts: mesh, UVs, waistband, hip clearance and the circle skirt's pattern."""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.garment.mesh_checks import (
    boundary_loops,
    degenerate_faces,
    nonmanifold_edges,
    uv_triangle_areas,
)
from loosefit.garment.skirt import SKIRT_RESOLUTIONS, STYLES, SkirtConfig, make_skirt
from loosefit.garment.waist_fit import WaistFit, waist_fit_from_points
from loosefit.types import GarmentTemplate
from tests.garment.test_waist_fit import WAIST_Z, ellipse_scale, profile_at, synthetic_body


@pytest.fixture(scope="module")
def body() -> np.ndarray:
    return synthetic_body()


@pytest.fixture(scope="module")
def waist(body: np.ndarray) -> WaistFit:
    return waist_fit_from_points(body, WAIST_Z, profile_depth=0.6)


@pytest.fixture(scope="module")
def skirts(waist: WaistFit) -> dict[tuple[str, str], GarmentTemplate]:
    return {
        (res, style): make_skirt(SkirtConfig.preset(res, style), waist)
        for res in SKIRT_RESOLUTIONS
        for style in STYLES
    }


def grid(skirt: GarmentTemplate) -> np.ndarray:
    """(R, S, 3) the skirt's vertices ring by ring."""
    config = skirt.meta["config"]
    return skirt.vertices.astype(np.float64).reshape(config["rings"], config["segments"], 3)


# --- config ------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"style": "pencil"}, "style"),
        ({"rings": 1}, "rings"),
        ({"segments": 4}, "segments"),
        ({"length": -0.2}, "length"),
        ({"flare": 95.0}, "flare"),
        ({"style": "circle", "segments": 36, "flutes": 7}, "flutes"),
        ({"uv_margin": 0.3}, "uv_margin"),
    ],
)
def test_config_rejects_bad_fields(kwargs: dict, field: str) -> None:
    with pytest.raises(LoosefitInputError, match=f"'{field}'"):
        SkirtConfig(**kwargs)


def test_preset_rejects_unknown_resolution() -> None:
    with pytest.raises(LoosefitInputError, match="resolution"):
        SkirtConfig.preset("huge")


# --- mesh and UVs ------------------------------------------------------------------------------


@pytest.mark.parametrize("res, low, high", [("cpu", 2000, 2500), ("paper", 9000, 9500)])
@pytest.mark.parametrize("style", STYLES)
def test_vertex_counts(skirts, res: str, low: int, high: int, style: str) -> None:
    skirt = skirts[res, style]
    assert low <= skirt.num_vertices <= high
    rings, segments = SKIRT_RESOLUTIONS[res][style]
    assert skirt.num_vertices == rings * segments
    assert skirt.faces.shape == (2 * (rings - 1) * segments, 3)


@pytest.mark.parametrize("res", list(SKIRT_RESOLUTIONS))
@pytest.mark.parametrize("style", STYLES)
def test_uvs_fill_the_square_without_flips(skirts, res: str, style: str) -> None:
    skirt = skirts[res, style]
    assert skirt.uvs.min() >= 0.0 and skirt.uvs.max() <= 1.0
    np.testing.assert_allclose(skirt.uvs.min(0), [0.02, 0.02], atol=1e-6)
    np.testing.assert_allclose(skirt.uvs.max(0), [0.98, 0.98], atol=1e-6)
    assert (uv_triangle_areas(skirt.uvs, skirt.face_uvs) > 0).all()
    # the layout tiles the square: UV areas sum to the inner square's
    assert uv_triangle_areas(skirt.uvs, skirt.face_uvs).sum() == pytest.approx(0.96**2, rel=1e-5)


@pytest.mark.parametrize("res", list(SKIRT_RESOLUTIONS))
@pytest.mark.parametrize("style", STYLES)
def test_faces_wound_outward(skirts, waist: WaistFit, res: str, style: str) -> None:
    skirt = skirts[res, style]
    tri = skirt.vertices.astype(np.float64)[skirt.faces]  # (F, 3, 3)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    radial = tri.mean(axis=1)[:, :2] - waist.center[:2]
    assert ((normal[:, :2] * radial).sum(axis=1) > 0).mean() > 0.95


@pytest.mark.parametrize("style", STYLES)
def test_mesh_is_clean(skirts, style: str) -> None:
    skirt = skirts["cpu", style]
    segments = skirt.meta["config"]["segments"]
    assert len(degenerate_faces(skirt.vertices, skirt.faces)) == 0
    assert len(nonmanifold_edges(skirt.faces)) == 0
    loops = boundary_loops(skirt.faces)
    assert len(loops) == 2 and all(len(loop) == segments for loop in loops)
    top = max(loops, key=lambda loop: skirt.vertices[loop, 2].mean())
    assert set(top.tolist()) == set(skirt.waist.tolist())


def test_diagonals_alternate(skirts) -> None:
    skirt = skirts["cpu", "aline"]
    segments = skirt.meta["config"]["segments"]
    quads = skirt.faces.reshape(-1, 2, 3)  # two triangles per quad
    # the shared diagonal of a quad either joins its top-left corner (i * S + j) or not
    top_left = quads[:, 1, 2]
    first_has_top_left = (quads[:, 0] == top_left[:, None]).any(axis=1)
    assert 0.4 < first_has_top_left.mean() < 0.6
    assert first_has_top_left[0] != first_has_top_left[1]
    assert first_has_top_left[0] != first_has_top_left[segments]


@pytest.mark.parametrize("style", STYLES)
def test_seam_vertices_have_two_uvs(skirts, style: str) -> None:
    skirt = skirts["cpu", style]
    rings, segments = (skirt.meta["config"][k] for k in ("rings", "segments"))
    uv_sets: list[set[int]] = [set() for _ in range(skirt.num_vertices)]
    for f, t in zip(skirt.faces.reshape(-1), skirt.face_uvs.reshape(-1), strict=True):
        uv_sets[f].add(int(t))
    counts = np.array([len(s) for s in uv_sets])
    seam = np.arange(rings) * segments
    assert (counts[seam] == 2).all()
    assert (np.delete(counts, seam) == 1).all()
    for vertex in seam:
        u, v = skirt.uvs[sorted(uv_sets[vertex])].T
        assert sorted(u.tolist()) == pytest.approx([0.02, 0.98])
        assert v[0] == v[1]
    # the seam is at the back of the body (+Y; the avatar faces -Y)
    rel = skirt.vertices[seam, :2] - skirt.vertices[:, :2].mean(axis=0)
    assert (rel[:, 1] > 0).all() and (np.abs(rel[:, 0]) < 1e-3).all()


@pytest.mark.parametrize("style", STYLES)
def test_waist_ring_fits_the_ellipse(skirts, waist: WaistFit, style: str) -> None:
    skirt = skirts["cpu", style]
    config = skirt.meta["config"]
    np.testing.assert_array_equal(skirt.waist, np.arange(config["segments"]))
    ring = skirt.vertices[skirt.waist].astype(np.float64)
    np.testing.assert_allclose(ring[:, 2], waist.height, atol=1e-6)
    axes = waist.radii + config["waist_ease"]
    scale = ellipse_scale(ring[:, :2] - waist.center[:2], axes)
    np.testing.assert_allclose(scale, 1.0, atol=1e-4)
    assert np.abs(skirt.uvs[: config["segments"], 1] - 0.98).max() < 1e-6  # waist on top in UV


@pytest.mark.parametrize("res", list(SKIRT_RESOLUTIONS))
@pytest.mark.parametrize("style", STYLES)
def test_rest_shape_clears_the_hips(skirts, waist: WaistFit, res: str, style: str) -> None:
    skirt = skirts[res, style]
    below = skirt.vertices[skirt.meta["config"]["segments"] :].astype(np.float64)
    radii = profile_at(waist.profile, below[:, 2])
    ok = np.isfinite(radii).all(axis=1)
    assert ok.mean() > 0.5  # the profile covers most of the skirt
    scale = ellipse_scale(below[ok, :2] - waist.center[:2], radii[ok] + 0.009)
    assert scale.min() >= 1.0


def test_rest_shape_clears_a_callable_profile() -> None:
    def hips(z: float) -> tuple[float, float] | None:
        return (0.22, 0.16) if 0.8 <= z <= 0.95 else None

    fit = WaistFit(center=[0.1, -0.05, 1.0], radii=[0.16, 0.11], height=1.0, profile=hips)
    skirt = make_skirt(SkirtConfig(style="aline"), fit)
    v = skirt.vertices.astype(np.float64)
    band = v[(v[:, 2] >= 0.8) & (v[:, 2] <= 0.95)]
    assert len(band) and ellipse_scale(band[:, :2] - [0.1, -0.05], [0.22, 0.16]).min() >= 1.0
    plain = make_skirt(SkirtConfig(style="aline"), WaistFit([0.1, -0.05, 1.0], [0.16, 0.11], 1.0))
    assert skirt.meta["ring_offsets"][-1] > plain.meta["ring_offsets"][-1]


@pytest.mark.parametrize("res", list(SKIRT_RESOLUTIONS))
@pytest.mark.parametrize("style", STYLES)
def test_edges_between_rings_have_the_pattern_length(skirts, res: str, style: str) -> None:
    skirt = skirts[res, style]
    config = skirt.meta["config"]
    step = config["length"] / (config["rings"] - 1)
    down = np.linalg.norm(np.diff(grid(skirt), axis=0), axis=2)  # (R - 1, S)
    np.testing.assert_allclose(down, step, rtol=1e-3)
    assert skirt.meta["max_edge_stretch"] < 1e-3


def test_hem_widths(skirts, waist: WaistFit) -> None:
    waist_radius = float(np.mean(waist.radii))
    hem = {s: np.linalg.norm(grid(skirts["cpu", s])[-1, :, :2], axis=1).mean() for s in STYLES}
    assert hem["flared"] >= 2 * waist_radius
    assert waist_radius < hem["aline"] < hem["flared"]


@pytest.mark.parametrize("res", list(SKIRT_RESOLUTIONS))
def test_circle_skirt_matches_its_flat_pattern(skirts, res: str) -> None:
    skirt = skirts[res, "circle"]
    config, meta = skirt.meta["config"], skirt.meta
    rings = grid(skirt)
    R, S = rings.shape[:2]
    step = config["length"] / (R - 1)
    r_in, r_out = meta["pattern_inner_radius"], meta["pattern_outer_radius"]
    assert r_out - r_in == pytest.approx(config["length"])
    # the annulus's inner circle is the waistband (the waist ellipse + ease)
    waist_len = np.linalg.norm(np.roll(rings[0], -1, 0) - rings[0], axis=1).sum()
    assert waist_len == pytest.approx(2 * np.pi * r_in, rel=2e-3)
    # every ring as long as the pattern's ring (an S-gon of radius r_in + i * step)
    around = np.linalg.norm(np.roll(rings, -1, axis=1) - rings, axis=2)  # (R, S)
    pattern = 2 * (r_in + step * np.arange(R)) * np.sin(np.pi / S)  # (R,) edge length
    np.testing.assert_allclose(around.sum(axis=1), S * pattern, rtol=0.01)
    assert meta["max_ring_error"] < 0.01
    # edges around a ring are close to the pattern's one by one
    ratio = around / pattern[:, None]
    assert np.percentile(ratio, 5) > 0.95 and np.percentile(ratio, 95) < 1.05
    # the hem is much longer than a plain cone's: folds hold the extra cloth
    assert np.max(meta["fold_amplitudes"]) > 0.02
    cone_hem = 2 * np.pi * np.linalg.norm(rings[-1, :, :2], axis=1).min()
    assert around[-1].sum() > 1.2 * cone_hem


def test_meta_records_the_config(skirts) -> None:
    skirt = skirts["cpu", "flared"]
    assert skirt.name == "skirt_flared"
    assert skirt.meta["config"]["style"] == "flared"
    assert skirt.meta["flare_deg"] == 30.0
    assert skirt.meta["waist_fit"]["height"] == WAIST_Z


def test_works_without_a_profile() -> None:
    fit = WaistFit(center=[0.0, 0.0, 0.95], radii=[0.15, 0.1], height=0.95)
    skirt = make_skirt(SkirtConfig(style="aline", flare=0.0, length=0.4), fit)
    ring_radii = np.linalg.norm(grid(skirt)[:, 0, :2], axis=1)  # the seam column
    np.testing.assert_allclose(ring_radii, 0.11, atol=1e-6)  # a cylinder: ry + ease
    assert skirt.vertices[:, 2].min() == pytest.approx(0.95 - 0.4, abs=1e-5)


def test_hem_loop_is_the_lower_opening() -> None:
    from loosefit.garment.mesh_checks import hem_loop

    # an open tube of two rings: the waist at z = 0, the hem at z = -1
    ring = [(np.cos(a), np.sin(a)) for a in np.linspace(0, 2 * np.pi, 6, endpoint=False)]
    v = np.array([(x, y, 0.0) for x, y in ring] + [(x, y, -1.0) for x, y in ring])
    f = [[i, (i + 1) % 6, 6 + i] for i in range(6)]
    f += [[(i + 1) % 6, 6 + (i + 1) % 6, 6 + i] for i in range(6)]
    assert sorted(hem_loop(v, np.array(f)).tolist()) == list(range(6, 12))
    assert len(hem_loop(v[:3], np.array([[0, 1, 2], [0, 2, 1]]))) == 0  # closed: none
