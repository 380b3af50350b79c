import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.geometry.skin_transfer import (
    closest_point_weights,
    diffuse_weights,
    garment_skin_weights,
)

# a body of one square in the plane z = 0, its four corners weighted to four joints
BODY = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
BODY_FACES = np.array([[0, 1, 2], [0, 2, 3]])
BODY_WEIGHTS = np.eye(4)


def test_closest_point_weights_blend_the_face_corners():
    garment = np.array([[0.0, 0.0, 0.1], [0.5, 0.5, -0.2], [0.75, 0.25, 0.0], [2.0, 0.0, 0.0]])
    w, distance = closest_point_weights(garment, BODY, BODY_FACES, BODY_WEIGHTS)
    np.testing.assert_allclose(distance, [0.1, 0.2, 0.0, 1.0], atol=1e-6)
    np.testing.assert_allclose(w[0], [1, 0, 0, 0], atol=1e-6)
    # on the diagonal: halfway between corners 0 and 2, in either face
    np.testing.assert_allclose(w[1], [0.5, 0, 0.5, 0], atol=1e-6)
    # in face (0, 1, 2): x = 0.75, y = 0.25 is 0.25 v0 + 0.5 v1 + 0.25 v2
    np.testing.assert_allclose(w[2], [0.25, 0.5, 0.25, 0], atol=1e-6)
    np.testing.assert_allclose(w[3], [0, 1, 0, 0], atol=1e-6)  # beyond corner 1


def _chain(n):
    """A strip of n - 1 triangles over vertices 0..n-1 (each i joined to i + 1 and i + 2)."""
    return np.array([[i, i + 1, i + 2] for i in range(n - 2)])


def test_diffused_weights_on_a_chain_are_the_mean_of_their_neighbours():
    n = 7
    faces = _chain(n)
    known = np.zeros(n, bool)
    known[[0, n - 1]] = True
    w = np.zeros((n, 2))
    w[0], w[-1] = [1, 0], [0, 1]
    out = diffuse_weights(w, faces, known)
    np.testing.assert_allclose(out[known], w[known])
    np.testing.assert_allclose(out.sum(1), 1.0)
    # the harmonic equations by a dense solve: L_uu W_u = -L_uk W_k
    adj = np.zeros((n, n))
    for a, b, c in faces:
        for i, j in ((a, b), (b, c), (c, a)):
            adj[i, j] = adj[j, i] = 1
    lap = np.diag(adj.sum(1)) - adj
    free = ~known
    want = np.linalg.solve(lap[free][:, free], -lap[free][:, known] @ w[known])
    np.testing.assert_allclose(out[free], want, atol=1e-12)


def test_a_part_with_no_known_vertex_keeps_its_weights_renormalised():
    faces = np.array([[0, 1, 2], [3, 4, 5]])  # two separate triangles
    w = np.array([[1, 0], [0.5, 0.5], [0.3, 0.3], [2, 2], [0, 3], [1, 3]], np.float64)
    known = np.array([True, False, False, False, False, False])
    out = diffuse_weights(w, faces, known)
    np.testing.assert_allclose(out[[1, 2]], [[1, 0], [1, 0]])  # diffused from vertex 0
    np.testing.assert_allclose(out[3:], w[3:] / w[3:].sum(1, keepdims=True))


def test_diffuse_weights_refuses_a_known_mask_of_the_wrong_length():
    with pytest.raises(LoosefitInputError) as err:
        diffuse_weights(np.ones((3, 2)), np.array([[0, 1, 2]]), np.ones(4, bool))
    assert err.value.field == "known"
    assert err.value.expected == "shape (3,)" and err.value.found == "(4,)"


def test_garment_skin_weights_near_the_body_keep_theirs_and_far_ones_are_refused():
    garment = np.array([[0.25, 0.75, 0.01], [0.75, 0.75, 0.01], [0.5, 0.9, 0.5]], np.float32)
    faces = np.array([[0, 1, 2]])
    w = garment_skin_weights(garment, faces, BODY, BODY_FACES, BODY_WEIGHTS, near=0.02)
    assert w.dtype == np.float32
    near_w, _ = closest_point_weights(garment[:2], BODY, BODY_FACES, BODY_WEIGHTS)
    np.testing.assert_allclose(w[:2], near_w, atol=1e-6)
    np.testing.assert_allclose(w[2], near_w.mean(0), atol=1e-6)  # its two neighbours' mean
    with pytest.raises(LoosefitInputError, match=r"within 0.5 m of the body.*found the nearest"):
        garment_skin_weights(garment + 3.0, faces, BODY, BODY_FACES, BODY_WEIGHTS, near=0.5)
