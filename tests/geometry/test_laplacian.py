import numpy as np
import pytest
import torch

from loosefit.errors import LoosefitInputError
from loosefit.geometry.laplacian import (
    MIN_COTANGENT_WEIGHT,
    Laplacian,
    apply_laplacian,
    laplacian_matrix,
)

# Unit square split along the diagonal 0-2: two right isosceles triangles.
SQUARE_V = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
SQUARE_F = np.array([[0, 1, 2], [0, 2, 3]])


def _grid(n: int, jitter: float = 0.0, equilateral: bool = False, seed: int = 0):
    """A flat n x n grid of vertices, two triangles per cell; (V, 3) float64, (F, 3)."""
    rng = np.random.default_rng(seed)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    x, y = j.astype(float), i.astype(float)
    if equilateral:  # rows shifted by half a cell: all triangles equilateral
        x, y = x + 0.5 * i, y * np.sqrt(3) / 2
    v = np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], 1)
    v[:, :2] += rng.uniform(-jitter, jitter, (n * n, 2))
    k = (i[:-1, :-1] * n + j[:-1, :-1]).ravel()
    if equilateral:
        f = np.concatenate([np.stack([k, k + 1, k + n], 1), np.stack([k + 1, k + n + 1, k + n], 1)])
    else:
        f = np.concatenate([np.stack([k, k + 1, k + n + 1], 1), np.stack([k, k + n + 1, k + n], 1)])
    interior = ((i > 0) & (i < n - 1) & (j > 0) & (j < n - 1)).ravel()
    return v, f, interior


def _naive_laplacian(v, f, kind):
    """Dense reference by loops over faces and corners."""
    V = len(v)
    W = np.zeros((V, V))
    for face in f:
        for k in range(3):
            c, a, b = face[k], face[(k + 1) % 3], face[(k + 2) % 3]
            if kind == "uniform":
                W[a, b] = W[b, a] = 1.0
            else:
                u, s = v[a] - v[c], v[b] - v[c]
                cot = np.dot(u, s) / np.linalg.norm(np.cross(u, s))
                W[a, b] += 0.5 * cot
                W[b, a] += 0.5 * cot
    edge = np.zeros((V, V), bool)
    for face in f:
        for k in range(3):
            edge[face[k], face[(k + 1) % 3]] = edge[face[(k + 1) % 3], face[k]] = True
    W = np.where(edge, np.maximum(W, MIN_COTANGENT_WEIGHT), 0.0)
    L = np.zeros((V, V))
    for i in range(V):
        if W[i].sum() > 0:
            L[i] = -W[i] / W[i].sum()
            L[i, i] = 1.0
    return L


def test_uniform_two_triangles_by_hand():
    L = laplacian_matrix(SQUARE_F, 4)
    expected = torch.tensor(
        [
            [1, -1 / 3, -1 / 3, -1 / 3],
            [-1 / 2, 1, -1 / 2, 0],
            [-1 / 3, -1 / 3, 1, -1 / 3],
            [-1 / 2, 0, -1 / 2, 1],
        ]
    )
    assert L.is_sparse and L.dtype == torch.float32 and L.shape == (4, 4)
    assert torch.allclose(L.to_dense(), expected, atol=1e-7)


def test_cotangent_right_isosceles_by_hand():
    # Legs 0-1, 1-2, 2-3, 3-0 face a 45 degree angle: w = cot(45) / 2 = 1/2. The diagonal
    # 0-2 faces two right angles: w = 0, raised to the small positive MIN_COTANGENT_WEIGHT.
    L = laplacian_matrix(torch.from_numpy(SQUARE_F), 4, "cotangent", SQUARE_V, dtype=torch.float64)
    e = MIN_COTANGENT_WEIGHT
    s = 1 + e
    expected = torch.tensor(
        [
            [1, -0.5 / s, -e / s, -0.5 / s],
            [-0.5, 1, -0.5, 0],
            [-e / s, -0.5 / s, 1, -0.5 / s],
            [-0.5, 0, -0.5, 1],
        ],
        dtype=torch.float64,
    )
    assert torch.allclose(L.to_dense(), expected, atol=1e-12)


def test_cotangent_obtuse_angles_are_clamped():
    # A flat kite: the diagonal 0-2 faces two obtuse angles (negative cotangents).
    v = np.array([[0.0, 0, 0], [1, -0.2, 0], [2, 0, 0], [1, 0.2, 0]])
    L = laplacian_matrix(SQUARE_F, 4, "cotangent", v, dtype=torch.float64).to_dense()
    off = L - torch.diag(torch.diag(L))
    assert (off <= 0).all()
    assert 0 < -L[0, 2] < 1e-3
    assert torch.allclose(L, torch.from_numpy(_naive_laplacian(v, SQUARE_F, "cotangent")))


@pytest.mark.parametrize("kind", ["uniform", "cotangent"])
def test_matches_naive_loop_on_a_jittered_grid(kind):
    v, f, _ = _grid(5, jitter=0.3)
    L = laplacian_matrix(f, len(v), kind, v, dtype=torch.float64).to_dense()
    assert torch.allclose(L, torch.from_numpy(_naive_laplacian(v, f, kind)), atol=1e-12)


@pytest.mark.parametrize("kind", ["uniform", "cotangent"])
def test_rows_sum_to_zero_and_constants_vanish(kind):
    v, f, _ = _grid(6, jitter=0.2)
    L = laplacian_matrix(f, len(v), kind, v)
    assert torch.allclose(torch.sparse.sum(L, 1).to_dense(), torch.zeros(len(v)), atol=1e-6)
    const = torch.full((len(v), 3), 2.5)
    assert torch.allclose(apply_laplacian(L, const), torch.zeros(len(v), 3), atol=1e-6)


def test_uniform_linear_function_vanishes_inside_a_regular_grid():
    v, f, interior = _grid(6)
    A = torch.tensor([[0.3, -1.2, 0.0], [2.0, 0.5, 0.0], [-0.7, 0.1, 1.0]], dtype=torch.float64)
    x = torch.from_numpy(v) @ A.T + torch.tensor([1.0, 2.0, 3.0], dtype=torch.float64)
    out = apply_laplacian(laplacian_matrix(f, len(v), dtype=torch.float64), x)
    assert torch.allclose(out[interior], torch.zeros(1, 3, dtype=torch.float64), atol=1e-12)
    assert out[~interior].abs().max() > 0.1  # the boundary is not an average of its ring


def test_cotangent_linear_precision_on_a_jittered_flat_mesh():
    # Acute triangles (jittered equilateral): no clamping, exact for linear functions.
    v, f, interior = _grid(6, jitter=0.1, equilateral=True)
    x = torch.from_numpy(v) @ torch.tensor([[1.0, 2.0, 0.0], [-0.5, 0.3, 0.0]]).double().T
    L = laplacian_matrix(f, len(v), "cotangent", v, dtype=torch.float64)
    assert torch.allclose(apply_laplacian(L, x)[interior], torch.zeros(1, 2).double(), atol=1e-12)


def test_isolated_vertex_gets_a_zero_row():
    L = laplacian_matrix(SQUARE_F, 6).to_dense()  # vertices 4 and 5 are in no face
    assert (L[4:] == 0).all() and (L[:, 4:] == 0).all()
    assert torch.allclose(L[:4, :4], laplacian_matrix(SQUARE_F, 4).to_dense())


def test_batched_shapes_match_per_item():
    v, f, _ = _grid(4, jitter=0.2)
    L = laplacian_matrix(f, len(v), "cotangent", v)
    x = torch.randn(2, 5, len(v), 3)
    out = apply_laplacian(L, x)
    assert out.shape == (2, 5, len(v), 3)
    assert torch.allclose(out[1, 3], L.to_dense() @ x[1, 3], atol=1e-6)
    assert apply_laplacian(L, x[0, 0, :, :2]).shape == (len(v), 2)


def test_gradcheck():
    L = laplacian_matrix(SQUARE_F, 4, "cotangent", SQUARE_V, dtype=torch.float64)
    x = torch.randn(2, 4, 3, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(lambda y: apply_laplacian(L, y), (x,))
    # float32 matrix, float64 input: converted to the input's dtype.
    L32 = laplacian_matrix(SQUARE_F, 4)
    assert torch.autograd.gradcheck(lambda y: apply_laplacian(L32, y), (x,))


def test_module_survives_to():
    v, f, _ = _grid(4)
    lap = Laplacian(f, len(v))
    x = torch.randn(3, len(v), 3, dtype=torch.float64)
    lap64 = lap.to(torch.float64)
    assert lap64.values.dtype == torch.float64 and lap64.indices.dtype == torch.long
    assert lap64.matrix.dtype == torch.float64 and lap64.matrix.is_coalesced()
    assert torch.allclose(lap64(x), apply_laplacian(laplacian_matrix(f, len(v)), x), atol=1e-6)
    assert lap.to("cpu")(x.float()).shape == (3, len(v), 3)
    assert lap.state_dict() == {}  # derived from the mesh, not saved


@pytest.mark.gpu
@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")
def test_module_on_cuda():
    v, f, _ = _grid(4)
    lap = Laplacian(f, len(v)).cuda()
    x = torch.randn(2, len(v), 3, device="cuda", requires_grad=True)
    out = lap(x)
    out.square().sum().backward()
    assert out.device.type == "cuda" and x.grad is not None
    assert torch.allclose(out.cpu(), Laplacian(f, len(v))(x.detach().cpu()), atol=1e-5)


def test_bad_input_names_the_field():
    with pytest.raises(LoosefitInputError, match="'kind'"):
        laplacian_matrix(SQUARE_F, 4, "mean")
    with pytest.raises(LoosefitInputError, match="'vertices'"):
        laplacian_matrix(SQUARE_F, 4, "cotangent")
    with pytest.raises(LoosefitInputError, match="'faces'"):
        laplacian_matrix(SQUARE_F, 3)
    with pytest.raises(LoosefitInputError, match=r"'x'.*\(\.\.\., 4, C\).*\(2, 5, 3\)"):
        apply_laplacian(laplacian_matrix(SQUARE_F, 4), torch.zeros(2, 5, 3))
