"""The evaluation metrics against naive loop versions, and on cases with known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from loosefit.errors import LoosefitInputError
from loosefit.eval.metrics import (
    hausdorff,
    inside_fraction,
    rmse,
    rmse_per_frame,
    sted,
    sted_speed_scaled,
    summarize,
)

# ---------------------------------------------------------------------------
# meshes


def _grid(n: int = 5, size: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """An n x n vertex grid in the z = 0 plane, two CCW triangles per cell."""
    xs = np.linspace(0.0, size, n)
    v = np.array([[x, y, 0.0] for y in xs for x in xs])
    faces = []
    for j in range(n - 1):
        for i in range(n - 1):
            a, b, c, d = j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i
            faces += [(a, b, c), (a, c, d)]
    return v, np.array(faces, np.int64)


def _cube(lo: float = 0.0, hi: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """A closed axis-aligned cube, 12 triangles, normals pointing outwards."""
    v = np.array([[x, y, z] for x in (lo, hi) for y in (lo, hi) for z in (lo, hi)], float)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    f = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    center = v.mean(0)
    for tri in f:  # the test's own premise: every face points away from the centre
        n = np.cross(v[tri[1]] - v[tri[0]], v[tri[2]] - v[tri[0]])
        assert n @ (v[tri].mean(0) - center) > 0
    return v, f


@pytest.fixture
def seqs() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A perturbed 5x5 grid: target (3, 25, 3) moving and wrinkling, pred = target + noise."""
    return _seqs_plain()


# ---------------------------------------------------------------------------
# naive versions: plain loops


def _naive_rmse(p, g):
    total, n = 0.0, 0
    for t in range(p.shape[0]):
        for v in range(p.shape[1]):
            total += sum((p[t, v, k] - g[t, v, k]) ** 2 for k in range(3))
            n += 1
    return math.sqrt(total / n)


def _naive_rmse_per_frame(p, g):
    out = []
    for t in range(p.shape[0]):
        total = 0.0
        for v in range(p.shape[1]):
            total += sum((p[t, v, k] - g[t, v, k]) ** 2 for k in range(3))
        out.append(math.sqrt(total / p.shape[1]))
    return out


def _point_triangle_distance(q, a, b, c):
    """Distance from q to triangle abc (Ericson, Real-Time Collision Detection, 5.1.5)."""
    ab, ac, ap = b - a, c - a, q - a
    d1, d2 = ab @ ap, ac @ ap
    if d1 <= 0 and d2 <= 0:
        return np.linalg.norm(q - a)
    bp = q - b
    d3, d4 = ab @ bp, ac @ bp
    if d3 >= 0 and d4 <= d3:
        return np.linalg.norm(q - b)
    vc = d1 * d4 - d3 * d2
    if vc <= 0 and d1 >= 0 and d3 <= 0:
        return np.linalg.norm(q - (a + d1 / (d1 - d3) * ab))
    cp = q - c
    d5, d6 = ab @ cp, ac @ cp
    if d6 >= 0 and d5 <= d6:
        return np.linalg.norm(q - c)
    vb = d5 * d2 - d1 * d6
    if vb <= 0 and d2 >= 0 and d6 <= 0:
        return np.linalg.norm(q - (a + d2 / (d2 - d6) * ac))
    va = d3 * d6 - d5 * d4
    if va <= 0 and (d4 - d3) >= 0 and (d5 - d6) >= 0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return np.linalg.norm(q - (b + w * (c - b)))
    denom = 1.0 / (va + vb + vc)
    return np.linalg.norm(q - (a + ab * vb * denom + ac * vc * denom))


def _naive_hausdorff(p, g, faces):
    out = []
    for t in range(p.shape[0]):
        worst = 0.0
        for queries, surface in ((p[t], g[t]), (g[t], p[t])):
            for q in queries:
                d = min(_point_triangle_distance(q, *surface[list(tri)]) for tri in faces)
                worst = max(worst, d)
        out.append(worst)
    return out


def _naive_sted(p, g, faces, fps, c=1.0):
    T, V, _ = p.shape
    edges = set()
    for tri in faces:
        for k in range(3):
            u, w = int(tri[k]), int(tri[(k + 1) % 3])
            edges.add((min(u, w), max(u, w)))
    nbrs = {v: set() for v in range(V)}
    for u, w in edges:
        nbrs[u].add(w)
        nbrs[w].add(u)
    used = [v for v in range(V) if nbrs[v]]

    sigmas = []
    for t in range(T):
        for v in used:
            ring = {v} | nbrs[v]
            weights, devs = [], []
            for a, b in edges:
                if a in ring or b in ring:
                    lg = np.linalg.norm(g[t, a] - g[t, b])
                    lp = np.linalg.norm(p[t, a] - p[t, b])
                    weights.append(lg)
                    devs.append((lp - lg) / lg)
            mu = sum(w * d for w, d in zip(weights, devs, strict=True)) / sum(weights)
            var = sum(w * (d - mu) ** 2 for w, d in zip(weights, devs, strict=True)) / sum(weights)
            sigmas.append(math.sqrt(var))
    spatial = sum(sigmas) / len(sigmas)

    rel = []
    dt = 1.0 / fps
    for t in range(T - 1):
        for v in used:
            lg = math.sqrt(np.sum((g[t + 1, v] - g[t, v]) ** 2) + (c * dt) ** 2)
            lp = math.sqrt(np.sum((p[t + 1, v] - p[t, v]) ** 2) + (c * dt) ** 2)
            rel.append(abs(lp - lg) / lg)
    temporal = sum(rel) / len(rel) if rel else 0.0
    return {"sted": math.sqrt(spatial**2 + temporal**2), "spatial": spatial, "temporal": temporal}


# ---------------------------------------------------------------------------
# rmse


def test_rmse_matches_naive_loop(seqs):
    pred, target, _ = seqs
    assert rmse(pred, target) == pytest.approx(_naive_rmse(pred, target), rel=1e-12)
    np.testing.assert_allclose(
        rmse_per_frame(pred, target), _naive_rmse_per_frame(pred, target), rtol=1e-12
    )


def test_rmse_of_identical_is_zero_and_of_a_1cm_shift_is_1cm(seqs):
    _, target, _ = seqs
    assert rmse(target, target.copy()) == 0.0
    np.testing.assert_array_equal(rmse_per_frame(target, target.copy()), 0.0)
    shift = np.array([0.006, 0.0, 0.008])  # |shift| = 0.01 m
    assert rmse(target + shift, target) == pytest.approx(0.01, rel=1e-9)
    np.testing.assert_allclose(rmse_per_frame(target + shift, target), 0.01, rtol=1e-9)


def test_rmse_accepts_torch_tensors(seqs):
    pred, target, _ = seqs
    got = rmse(torch.tensor(pred, requires_grad=True), torch.tensor(target))
    assert got == pytest.approx(rmse(pred, target), rel=1e-12)
    assert isinstance(got, float)


# ---------------------------------------------------------------------------
# hausdorff


def test_hausdorff_matches_brute_force(seqs):
    pred, target, faces = seqs
    got = hausdorff(pred, target, faces)
    assert got.shape == (3,)
    np.testing.assert_allclose(got, _naive_hausdorff(pred, target, faces), atol=1e-5)


def test_hausdorff_sees_a_bump_on_either_side():
    """A bump on one surface counts whichever of the two is the prediction."""
    v, f = _grid()
    target = v[None].copy()
    pred = target.copy()
    pred[0, 12, 2] = 0.3  # the middle vertex lifted 30 cm
    np.testing.assert_allclose(hausdorff(pred, target, f), [0.3], atol=1e-6)
    np.testing.assert_allclose(hausdorff(target, pred, f), [0.3], atol=1e-6)


def test_hausdorff_of_a_normal_translation_is_its_distance():
    v, f = _grid()
    target = np.stack([v, v + [0.1, -0.2, 0.0]])  # a flat plane z = 0, moving in-plane
    d = 0.037
    pred = target + [0.0, 0.0, d]
    np.testing.assert_allclose(hausdorff(pred, target, f), [d, d], atol=1e-6)
    np.testing.assert_allclose(hausdorff(target, target, f), [0.0, 0.0], atol=1e-6)


# ---------------------------------------------------------------------------
# sted


def test_sted_matches_naive_loop(seqs):
    pred, target, faces = seqs
    # one vertex that no face uses: left out of both means
    pred = np.concatenate([pred, np.full((3, 1, 3), 2.0)], axis=1)
    target = np.concatenate([target, np.full((3, 1, 3), -2.0)], axis=1)
    for fps, c in ((30.0, 1.0), (10.0, 0.3)):
        got = sted_speed_scaled(pred, target, faces, fps, speed_scale=c)
        want = _naive_sted(pred, target, faces, fps, c)
        assert got.keys() == {"sted", "spatial", "temporal"}
        for key in want:
            assert isinstance(got[key], float)
            assert got[key] == pytest.approx(want[key], rel=1e-9), key
        assert got["spatial"] > 0 and got["temporal"] > 0


def test_sted_of_a_rigid_translation_is_zero_and_of_a_stretch_positive(seqs):
    _, target, faces = seqs
    moved = target + [0.3, -0.1, 0.25]
    s = sted_speed_scaled(moved, target, faces, fps=30.0)
    assert s["sted"] == pytest.approx(0.0, abs=1e-12)

    stretched = target * [1.2, 1.0, 1.0]  # uneven stretch: x edges longer, y edges not
    s = sted_speed_scaled(stretched, target, faces, fps=30.0)
    assert s["spatial"] > 0.01
    assert s["temporal"] > 0  # the sequence moves along x, so its speeds change too
    assert s["sted"] == pytest.approx(math.hypot(s["spatial"], s["temporal"]), rel=1e-12)


def test_sted_spatial_ignores_uniform_scaling_and_single_frames(seqs):
    _, target, faces = seqs
    # one frame: no temporal edges
    s = sted_speed_scaled(target[:1] * 1.5, target[:1], faces, fps=30.0)
    assert s["spatial"] == pytest.approx(0.0, abs=1e-12)
    assert s["temporal"] == 0.0


# ---------------------------------------------------------------------------
# inside_fraction


def test_inside_fraction_of_half_inside_points_is_half():
    body, bf = _cube()
    rng = np.random.default_rng(1)
    inside = rng.uniform(0.1, 0.9, (10, 3))
    outside = rng.uniform(0.1, 0.9, (10, 3)) + [0.0, 0.0, 1.5]
    garment = np.concatenate([inside, outside])[None]
    np.testing.assert_allclose(inside_fraction(garment, body[None], bf), [0.5])


def test_inside_fraction_matches_naive_box_test():
    body, bf = _cube(-0.5, 0.5)
    rng = np.random.default_rng(2)
    offsets = np.array([[0.0, 0.0, 0.0], [0.3, 0.0, -0.2], [1.0, 1.0, 1.0]])
    bodies = body[None] + offsets[:, None]
    garment = offsets[:, None] + rng.uniform(-0.8, 0.8, (3, 40, 3))
    # keep clear of the faces, where float32 may go either way
    local = garment - offsets[:, None]
    near = (np.abs(np.abs(local) - 0.5) < 1e-3).any(-1)
    garment[near] = 5.0
    want = []
    for t in range(3):
        n = 0
        for v in range(garment.shape[1]):
            if all(-0.5 < garment[t, v, k] - offsets[t, k] < 0.5 for k in range(3)):
                n += 1
        want.append(n / garment.shape[1])
    assert 0 < min(want)
    np.testing.assert_allclose(inside_fraction(garment, bodies, bf), want)


# ---------------------------------------------------------------------------
# summarize


def test_summarize_in_cm_and_m(seqs):
    pred, target, faces = seqs
    s = summarize(pred, target, faces)
    assert s.keys() == {"rmse_cm", "hausdorff_cm", "sted", "sted_spatial", "sted_temporal"}
    assert s["rmse_cm"] == pytest.approx(100 * _naive_rmse(pred, target), rel=1e-9)
    h = np.mean(_naive_hausdorff(pred, target, faces))
    assert s["hausdorff_cm"] == pytest.approx(100 * h, abs=1e-3)
    assert s["sted"] == pytest.approx(sted(pred, target, faces)["sted"], rel=1e-12)
    m = summarize(pred, target, faces, units="m")
    assert m["rmse_m"] == pytest.approx(s["rmse_cm"] / 100, rel=1e-12)
    assert m["hausdorff_m"] == pytest.approx(s["hausdorff_cm"] / 100, rel=1e-12)
    assert m["sted"] == s["sted"]


# ---------------------------------------------------------------------------
# bad input


def _bad_cases():
    v, f = _grid(3)
    x = np.stack([v, v + 0.01])  # (2, 9, 3)
    nan = x.copy()
    nan[1, 4, 0] = np.nan
    body, bf = _cube()
    return [
        ("rmse", "pred", lambda: rmse(x[..., :2], x[..., :2])),
        ("rmse", "pred", lambda: rmse(x[0], x[0])),
        ("rmse", "target", lambda: rmse(x, x[:1])),
        ("rmse", "target", lambda: rmse(x, nan)),
        ("rmse_per_frame", "target", lambda: rmse_per_frame(x, x[:, :8])),
        ("hausdorff", "faces", lambda: hausdorff(x, x, f + 1)),
        ("hausdorff", "faces", lambda: hausdorff(x, x, f.astype(float))),
        ("hausdorff", "faces", lambda: hausdorff(x, x, f[:, :2])),
        (
            "sted_speed_scaled",
            "faces",
            lambda: sted_speed_scaled(x, x, np.array([[0, 1, 1]]), 30.0),
        ),
        ("sted_speed_scaled", "fps", lambda: sted_speed_scaled(x, x, f, 0.0)),
        ("sted_speed_scaled", "pred", lambda: sted_speed_scaled(nan, x, f, 30.0)),
        # zero-length edges
        ("sted_speed_scaled", "target", lambda: sted_speed_scaled(x, np.zeros_like(x), f, 30.0)),
        ("sted", "pred", lambda: sted(nan, x, f)),
        ("sted", "target", lambda: sted(x, np.zeros_like(x), f)),
        ("sted", "dt", lambda: sted(x, x, f, dt=0.0)),
        ("inside_fraction", "body", lambda: inside_fraction(x, body[None], bf)),
        ("inside_fraction", "body_faces", lambda: inside_fraction(x[:1], body[None], bf + 8)),
        ("summarize", "units", lambda: summarize(x, x, f, units="mm")),
        ("summarize", "target", lambda: summarize(x, x[:, :5], f)),
    ]


@pytest.mark.parametrize("case", range(len(_bad_cases())))
def test_bad_input_raises_loosefit_input_error(case):
    source, field, call = _bad_cases()[case]
    with pytest.raises(LoosefitInputError) as err:
        call()
    assert (err.value.source, err.value.field) == (source, field)


# sted: Vasa and Skala's tool's definition


def test_sted_of_a_uniform_scale_of_a_still_mesh_is_zero():
    v, f = _grid()
    target = np.stack([v] * 4)
    s = sted(1.3 * target, target, f)
    assert s["spatial"] == pytest.approx(0.0, abs=1e-12)  # every edge stretched alike
    assert s["temporal"] == pytest.approx(0.0, abs=1e-12)  # nothing moves: all dt
    assert s["sted"] == pytest.approx(0.0, abs=1e-12)


def test_sted_of_a_one_frame_lag_by_hand():
    # the grid slides 1 cm a frame along x; the prediction lags one frame behind it
    v, f = _grid()  # 1 x 1 m, diameter sqrt(2)
    T = 12
    target = np.stack([v + [0.01 * t, 0.0, 0.0] for t in range(T)])
    pred = np.concatenate([target[:1], target[:-1]])
    s = sted(pred, target, f)
    assert s["spatial"] == pytest.approx(0.0, abs=1e-12)  # rigid: edges keep their lengths
    u, dt = 0.01 / math.sqrt(2.0), 3.0e-4
    moving = math.sqrt(u**2 + dt**2)  # every temporal edge of the target
    # only the first temporal edge differs (the prediction stands still: dt), and the
    # window's mean of the target's is the same everywhere
    want = (moving - dt) / moving / (T - 1)
    assert s["temporal"] == pytest.approx(want, rel=1e-9)
    assert s["sted"] == pytest.approx(9.144e-5 * want, rel=1e-9)
    # the window's mean divides: a target that speeds up halfway
    steps = np.r_[np.full(6, 0.01), np.full(5, 0.03)]
    target = np.stack([v + [x, 0.0, 0.0] for x in np.r_[0.0, np.cumsum(steps)]])
    pred = target.copy()
    pred[1:, :, 0] += 0.005  # one frame's step 5 mm longer, the rest as the target's
    s = sted(pred, target, f, window=2)
    lengths = np.sqrt((steps / math.sqrt(2.0)) ** 2 + dt**2)
    first = math.sqrt((0.015 / math.sqrt(2.0)) ** 2 + dt**2)
    assert s["temporal"] == pytest.approx((first - lengths[0]) / lengths[:3].mean() / 11, rel=1e-9)


def test_sted_counts_unused_vertices_as_zero_and_weighs_time():
    pred, target, f = _seqs_plain()
    s = sted(pred, target, f)
    assert s["sted"] == pytest.approx(math.hypot(s["spatial"], 9.144e-5 * s["temporal"]))
    assert s["spatial"] == pytest.approx(sted_speed_scaled(pred, target, f, 30.0)["spatial"])
    # a vertex no face uses adds a zero to the spatial mean
    extra = lambda x: np.concatenate([x, x[:, :1] + 5.0], axis=1)  # noqa: E731
    more = sted(extra(pred), extra(target), f)
    assert more["spatial"] == pytest.approx(s["spatial"] * 25 / 26)
    with pytest.raises(LoosefitInputError, match="window"):
        sted(pred, target, f, window=-1)


def _seqs_plain():
    """The fixture ``seqs``'s sequences (a test that changes them builds its own)."""
    rng = np.random.default_rng(0)
    v, f = _grid()
    target = np.stack([v + [0.05 * t, 0.0, 0.02 * t] for t in range(3)])
    target = target + rng.normal(0.0, 0.03, target.shape)
    pred = target + rng.normal(0.0, 0.02, target.shape)
    return pred, target, f
