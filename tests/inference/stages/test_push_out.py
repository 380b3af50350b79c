"""The baselines' push-out on a cube, whose flat faces give every answer by hand: a vertex
inside or closer than epsilon ends epsilon outside along the face's normal, the rest stay."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from loosefit.errors import LoosefitInputError
from loosefit.geometry.query import Surface
from loosefit.inference.stages.push_out import PushOutHandler
from tests.meshes import cube

EPS = 0.01


def _resolve(garment: np.ndarray, faces: np.ndarray):
    body = Surface(*cube(1.0))  # its top face at z = 0.5, normal +z
    handler = PushOutHandler(faces, len(garment), epsilon=EPS, reach=0.2)
    return handler.resolve(torch.from_numpy(garment), body)


def test_close_and_inside_vertices_end_epsilon_above_the_face():
    garment = np.array([[0.0, 0.0, 0.45], [0.1, 0.0, 0.505], [0.0, 0.1, 0.7]], np.float32)
    faces = np.array([[0, 1, 2]])
    r = _resolve(garment, faces)
    want = garment.astype(np.float64).copy()
    want[0, 2] = want[1, 2] = 0.5 + EPS  # 5 cm inside and 5 mm outside: both to 1 cm out
    np.testing.assert_allclose(r.vertices.numpy(), want, atol=1e-6)
    assert r.vertices.dtype == torch.float32
    assert r.depth_before == pytest.approx(EPS + 0.05, abs=1e-6)  # max(eps - ds)
    assert r.depth_after == 0.0
    assert (r.inside_before, r.inside_after, r.moved, r.iterations) == (1, 0, 2, 2)
    # the Laplacian change: a plain loop over the triangle's 1-rings (each the other two)
    d = want - garment.astype(np.float64)
    lap = np.array([d[i] - d[[j for j in range(3) if j != i]].mean(0) for i in range(3)])
    assert r.laplacian_change == pytest.approx(np.sqrt((lap**2).sum(-1).mean()), rel=1e-6)


def test_a_garment_clear_of_the_body_is_left_as_it_is():
    garment = np.array([[0.0, 0.0, 0.6], [0.1, 0.0, 0.65], [0.0, 0.1, 0.9]], np.float32)
    r = _resolve(garment, np.array([[0, 1, 2]]))
    np.testing.assert_array_equal(r.vertices.numpy(), garment)
    assert (r.moved, r.iterations, r.inside_before, r.depth_before) == (0, 1, 0, 0.0)
    assert r.laplacian_change == 0.0


def test_bad_settings_and_garments_are_refused():
    faces = np.array([[0, 1, 2]])
    for eps, reach in ((0.0, 0.1), (0.01, -1.0), (float("nan"), 0.1)):
        with pytest.raises(LoosefitInputError, match=r"PushOutHandler: field 'epsilon, reach'"):
            PushOutHandler(faces, 3, epsilon=eps, reach=reach)
    handler = PushOutHandler(faces, 3)
    with pytest.raises(LoosefitInputError, match=r"expected \(3, 3\), found \(4, 3\)"):
        handler.resolve(torch.zeros(4, 3), Surface(*cube(1.0)))
