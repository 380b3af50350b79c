"""SSDR baseline: a tube bent by three known bones, skinning against a naive loop, bad inputs."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from loosefit.errors import LoosefitInputError
from loosefit.model.ssdr import SkinningDecomposition, SSDRConfig, decompose, fit_transforms


def _tube(around: int = 10, rings: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """A 1 m tall open cylinder of radius 0.15 m: rest (V, 3), V = 200, and faces (F, 3)."""
    a, y = np.meshgrid(np.linspace(0, 2 * np.pi, around, endpoint=False), np.linspace(0, 1, rings))
    rest = np.stack([0.15 * np.cos(a.ravel()), y.ravel(), 0.15 * np.sin(a.ravel())], -1)
    faces = []
    for r in range(rings - 1):
        for c in range(around):
            i, j = r * around + c, r * around + (c + 1) % around
            faces += [[i, j, j + around], [i, j + around, i + around]]
    return rest, np.array(faces)


def _motion(rest: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(T, V, 3) frames: three chained rigid bones, joints at y = 1/3, 2/3 blended over 0.2 m."""
    up = np.clip((rest[:, 1:2] - [1 / 3, 2 / 3]) / 0.2 + 0.5, 0, 1)  # (V, 2) blend across joints
    w = np.c_[1 - up[:, :1], up[:, :1] - up[:, 1:], up[:, 1:]]  # (V, 3), <= 2 nonzeros per row
    frames = []
    for s in t:
        root = np.eye(4)
        root[:3, :3] = Rotation.from_rotvec([0, 0.3 * np.sin(s), 0]).as_matrix()
        root[:3, 3] = [0.2 * np.sin(0.5 * s), 0.05 * s, 0]
        bones = [root]
        for axis, joint in ([1, 0, 0], 1 / 3), ([0, 0, 1], 2 / 3):
            bend = np.eye(4)
            bend[:3, :3] = Rotation.from_rotvec(
                0.6 * np.sin(s + joint) * np.array(axis)
            ).as_matrix()
            bend[:3, 3] = [0, joint, 0] - bend[:3, :3] @ [0, joint, 0]
            bones.append(bones[-1] @ bend)
        hom = np.c_[rest, np.ones(len(rest))]
        frames.append(np.einsum("vb,bij,vj->vi", w, np.stack(bones), hom)[:, :3])
    return np.stack(frames)


def _naive_skin(d: SkinningDecomposition, transforms: np.ndarray) -> np.ndarray:
    """(T, V, 3) by a loop over frames, vertices and bones."""
    out = np.zeros((len(transforms), len(d.rest), 3))
    for t, a in enumerate(transforms):
        for i, r in enumerate(d.rest):
            for b in range(d.bones):
                out[t, i] += d.weights[i, b] * (a[b, :, :3] @ r + a[b, :, 3])
    return out


def _random_decomposition(v: int = 12, b: int = 3, seed: int = 0) -> SkinningDecomposition:
    rng = np.random.default_rng(seed)
    w = rng.random((v, b))
    return SkinningDecomposition(
        rest=rng.normal(size=(v, 3)).astype(np.float32),
        weights=(w / w.sum(1, keepdims=True)).astype(np.float32),
        transforms=rng.normal(size=(2, b, 3, 4)).astype(np.float32),
        rmse=0.0,
        frame_index=np.arange(2),
    )


CONFIG = SSDRConfig(bones=3, max_influences=2, max_frames=None)


@pytest.fixture(scope="module")
def tube():
    rest, faces = _tube()
    t = np.linspace(0, 6, 30)
    held_out = np.arange(30) % 3 == 1
    return rest, faces, _motion(rest, t[~held_out]), _motion(rest, t[held_out])


@pytest.fixture(scope="module")
def fitted(tube):
    rest, faces, train, _ = tube
    return decompose(train, rest, CONFIG, faces=faces)


def test_decompose_recovers_three_bones(tube, fitted):
    rest, _, train, _ = tube
    assert fitted.weights.shape == (200, 3) and fitted.transforms.shape == (20, 3, 3, 4)
    assert fitted.rmse < 2e-3  # metres
    np.testing.assert_array_equal(fitted.frame_index, np.arange(20))
    np.testing.assert_allclose(fitted.weights.sum(1), 1, atol=1e-5)
    assert (fitted.weights >= 0).all() and ((fitted.weights > 0).sum(1) <= 2).all()
    err = np.linalg.norm(fitted.skin(fitted.transforms) - train, axis=-1)  # (T, V)
    assert np.sqrt((err**2).mean()) == pytest.approx(fitted.rmse, rel=1e-4)
    assert err.max() < 0.01
    rot = fitted.transforms[..., :3].astype(np.float64)  # Dem Bones' bones are rigid
    np.testing.assert_allclose(
        rot @ rot.swapaxes(-1, -2), np.broadcast_to(np.eye(3), rot.shape), atol=1e-5
    )


def test_fit_transforms_on_held_out_frames(tube, fitted):
    held_out = tube[3]
    a = fit_transforms(fitted, held_out)
    assert a.shape == (10, 3, 3, 4) and a.dtype == np.float32
    err = np.linalg.norm(fitted.skin(a) - held_out, axis=-1)
    assert np.sqrt((err**2).mean()) < 2 * fitted.rmse + 1e-3
    # on the fitted frames, affine least squares is at least as good as Dem Bones' rigid bones
    train_fit = fitted.skin(fit_transforms(fitted, tube[2]))
    assert np.sqrt(((train_fit - tube[2]) ** 2).sum(-1).mean()) <= fitted.rmse + 1e-6


def test_fit_transforms_is_exact_for_skinned_frames():
    d = _random_decomposition(v=40)
    np.testing.assert_allclose(fit_transforms(d, d.skin(d.transforms)), d.transforms, atol=1e-4)


def test_max_frames_picks_a_seeded_subset(tube):
    rest, faces, train, _ = tube
    cfg = SSDRConfig(bones=3, iterations=5, max_frames=8, seed=3)
    a, b = decompose(train, rest, cfg, faces=faces), decompose(train, rest, cfg, faces=faces)
    assert a.transforms.shape[0] == 8 and len(np.unique(a.frame_index)) == 8
    assert (np.diff(a.frame_index) > 0).all() and a.frame_index.max() < 20
    np.testing.assert_array_equal(a.frame_index, b.frame_index)


def test_skin_matches_naive_loop_and_torch():
    d = _random_decomposition()
    ref = _naive_skin(d, d.transforms)
    np.testing.assert_allclose(d.skin(d.transforms), ref, atol=1e-5)
    out = d.skin(torch.from_numpy(d.transforms))
    assert isinstance(out, torch.Tensor) and out.dtype == torch.float32
    np.testing.assert_allclose(out.numpy(), ref, atol=1e-5)
    a = torch.from_numpy(d.transforms).double().requires_grad_()
    assert torch.autograd.gradcheck(d.skin, (a,))


def test_save_load_round_trip(tmp_path):
    d = _random_decomposition()
    d.save(tmp_path / "ssdr.npz")
    e = SkinningDecomposition.load(tmp_path / "ssdr.npz")
    for k in ("rest", "weights", "transforms", "frame_index"):
        np.testing.assert_array_equal(getattr(e, k), getattr(d, k))
    assert e.rmse == d.rmse


def test_bad_inputs(tube, tmp_path):
    rest, faces, train, _ = tube
    bad = train.copy()
    bad[0, 0, 0] = np.nan
    cases = [
        (lambda: decompose(bad, rest, CONFIG, faces=faces), "frames"),
        (lambda: decompose(train, rest[:-1], CONFIG, faces=faces), "rest"),
        (lambda: decompose(train[0], rest, CONFIG, faces=faces), "frames"),
        (lambda: decompose(train, rest, CONFIG, faces=faces + 1), "faces"),
        (lambda: decompose(train, rest, SSDRConfig(bones=0), faces=faces), "bones"),
        (lambda: decompose(train, rest, SSDRConfig(bones=201), faces=faces), "bones"),
        (lambda: decompose(train, rest, SSDRConfig(threads=0), faces=faces), "threads"),
        (lambda: fit_transforms(_random_decomposition(), train), "frames"),
        (lambda: _random_decomposition().skin(np.zeros((2, 4, 3, 4))), "transforms"),
    ]
    for call, field in cases:
        with pytest.raises(LoosefitInputError, match=field):
            call()
    np.savez(tmp_path / "bad.npz", rest=rest)
    with pytest.raises(LoosefitInputError, match="weights"):
        SkinningDecomposition.load(tmp_path / "bad.npz")
