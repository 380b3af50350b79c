"""Skinning decomposition (SSDR) of a garment sequence: the ablation's linear baseline (paper 4.2).

Smooth Skinning Decomposition with Rigid bones (Le and Deng 2012) approximates
every frame of a mesh sequence by linear blend skinning of the rest mesh with
``B`` bones,

    x_ti = sum_b w_ib A_tb [r_i; 1],

with sparse convex weights ``w`` (V, B) shared by all frames and one 3 x 4
transform ``A_tb`` per frame and bone. :func:`decompose` fits both with EA's
Dem Bones (the ``py-dem-bones`` bindings); :func:`fit_transforms` then finds the
transforms of new frames for fixed weights (targets for the linear decoder);
:meth:`SkinningDecomposition.skin` maps transforms back to vertices.

Dem Bones' layout, as the bindings take and return it (checked on a small
example): rest ``u`` (3, V); frames ``v`` (3 T, V), rows ``3 t + c`` holding
coordinate c of frame t; weights ``get_weights()`` (B, V); transforms ``m``
(4 T, 4 B), block ``(t, b)`` the 4 x 4 column-vector matrix of bone b at frame
t (``get_transformations()`` returns bone 0 only); ``rmse()`` is the RMS of the
per-vertex Euclidean error. It needs the faces (``fv``) to initialise more than
one bone (without them it silently keeps one) and for its weight smoothing; it
may prune bones and return fewer than asked. Its transforms are rigid.
"""

from __future__ import annotations

import ctypes
import os
import re
from contextlib import contextmanager
from dataclasses import dataclass
from os import PathLike

import numpy as np
import torch

from loosefit.errors import LoosefitInputError


@dataclass
class SSDRConfig:
    """Settings of a Dem Bones decomposition."""

    bones: int = 32  # bones asked for (Dem Bones may prune some), 1 <= bones <= V
    iterations: int = 30  # global iterations (transforms, then weights)
    init_iterations: int = 10  # clustering iterations per bone split when initialising
    transform_iterations: int = 5  # transform updates per global iteration
    weight_iterations: int = 3  # weight updates per global iteration
    max_influences: int = 4  # nonzero weights per vertex
    weight_smoothness: float = 1e-4  # Laplacian smoothness of the weights
    max_frames: int | None = 2000  # fit on a seeded random subset of this many frames; None: all
    seed: int = 0  # seed of that subset
    threads: int | None = 1  # OpenMP threads for Dem Bones (1: fastest on a busy box); None: all


@dataclass
class SkinningDecomposition:
    """Weights and per-frame bone transforms approximating a sequence by skinning.

    Attributes:
        rest: (V, 3) float32 rest positions the transforms act on.
        weights: (V, B) float32 skinning weights, rows summing to 1, at most
            ``max_influences`` nonzeros per row.
        transforms: (T, B, 3, 4) float32 bone transforms of the fitted frames.
        rmse: RMS per-vertex distance, metres, of ``skin(transforms)`` to those frames.
        frame_index: (T,) int64 index of each fitted frame in the input sequence.
    """

    rest: np.ndarray
    weights: np.ndarray
    transforms: np.ndarray
    rmse: float
    frame_index: np.ndarray

    @property
    def bones(self) -> int:
        return self.weights.shape[1]

    def design(self) -> np.ndarray:
        """(V, 4 B) float64 matrix ``D`` with ``D[i, 4 b + k] = w_ib [r_i; 1]_k``.

        Vertices are linear in the transforms: ``x (V, 3) = D @ X`` where
        ``X (4 B, 3)`` stacks the transposed ``A_b`` (see :func:`_stack`).
        """
        hom = np.concatenate([self.rest, np.ones((len(self.rest), 1))], 1).astype(np.float64)
        return (self.weights[:, :, None] * hom[:, None, :]).reshape(len(hom), -1)  # (V, 4 B)

    def skin(self, transforms: np.ndarray | torch.Tensor) -> np.ndarray | torch.Tensor:
        """Linear blend skinning of the rest mesh, ``x_i = sum_b w_ib A_b [r_i; 1]``.

        Args:
            transforms: (..., B, 3, 4) bone transforms, numpy or torch (then
                differentiable, on its device and dtype).

        Returns:
            (..., V, 3) vertices, of the same kind as ``transforms``.
        """
        is_torch = isinstance(transforms, torch.Tensor)
        a = transforms if is_torch else np.asarray(transforms)
        if tuple(a.shape[-3:]) != (self.bones, 3, 4):
            found = f"shape {tuple(a.shape)}"
            raise LoosefitInputError("skin", "transforms", f"(..., {self.bones}, 3, 4)", found)
        if is_torch:
            d = torch.as_tensor(self.design(), dtype=a.dtype, device=a.device)
            return d @ _stack(a)  # (..., V, 3)
        dtype = np.result_type(a.dtype, np.float32)
        return (self.design() @ _stack(a.astype(np.float64))).astype(dtype)  # (..., V, 3)

    def save(self, path: str | PathLike) -> None:
        """Write the decomposition to an ``.npz`` file."""
        np.savez(path, **{k: np.asarray(v) for k, v in vars(self).items()})

    @classmethod
    def load(cls, path: str | PathLike) -> SkinningDecomposition:
        """Read a decomposition written by :meth:`save`."""
        from loosefit.types import load_npz

        z = load_npz(path, "a skinning decomposition .npz", tuple(cls.__dataclass_fields__))
        return cls(
            rest=z["rest"].astype(np.float32),
            weights=z["weights"].astype(np.float32),
            transforms=z["transforms"].astype(np.float32),
            rmse=float(z["rmse"]),
            frame_index=z["frame_index"].astype(np.int64),
        )


def _stack(transforms):
    """(..., B, 3, 4) transforms -> (..., 4 B, 3), row ``4 b + k`` holding ``A_b[:, k]``."""
    t = transforms.swapaxes(-1, -2)  # (..., B, 4, 3)
    return t.reshape(*t.shape[:-3], -1, 3)


def _check_points(x, source: str, field: str, shape: tuple) -> np.ndarray:
    """Float64 copy of x, checked against ``shape`` (None: any size) and for NaN/inf."""
    x = np.asarray(x, dtype=np.float64)
    ok = x.ndim == len(shape) and x.size > 0
    if not ok or any(s not in (None, n) for s, n in zip(shape, x.shape, strict=False)):
        want = "(" + ", ".join("*" if s is None else str(s) for s in shape) + ")"
        raise LoosefitInputError(source, field, f"shape {want}", f"shape {x.shape}")
    if not np.isfinite(x).all():
        raise LoosefitInputError(source, field, "finite values", "NaN or inf")
    return x


@contextmanager
def _omp_threads(n: int | None):
    """Limit every OpenMP runtime loaded in the process to n threads (None: leave them).

    Dem Bones binds to whichever libgomp was loaded first into the global scope,
    its bundled copy or torch's, so both are set (Linux; a no-op elsewhere).
    """
    libs = []
    if n is not None and os.path.exists("/proc/self/maps"):
        with open("/proc/self/maps") as f:
            paths = {line.split()[-1] for line in f if re.search(r"/lib[gi]omp[^/]*\.so", line)}
        libs = [ctypes.CDLL(p) for p in sorted(paths)]
    previous = [lib.omp_get_max_threads() for lib in libs]
    for lib in libs:
        lib.omp_set_num_threads(n)
    try:
        yield
    finally:
        for lib, k in zip(libs, previous, strict=True):
            lib.omp_set_num_threads(k)


def decompose(
    frames: np.ndarray, rest: np.ndarray, config: SSDRConfig | None = None, *, faces: np.ndarray
) -> SkinningDecomposition:
    """Fit an SSDR decomposition (Le and Deng 2012) of a sequence with Dem Bones.

    Args:
        frames: (T, V, 3) vertex positions, metres.
        rest: (V, 3) rest positions, same vertex order.
        config: the settings; default :class:`SSDRConfig`.
        faces: (F, k) integer polygons (k >= 3) of the mesh; Dem Bones needs
            them to initialise several bones and to smooth the weights.

    Returns:
        The decomposition on ``min(T, max_frames)`` frames (``frame_index``),
        with at most ``config.bones`` bones.
    """
    from py_dem_bones import DemBones

    cfg = config or SSDRConfig()
    frames = _check_points(frames, "decompose", "frames", (None, None, 3))
    t, v = frames.shape[:2]
    rest = _check_points(rest, "decompose", "rest", (v, 3))
    faces = np.asarray(faces)
    if faces.ndim != 2 or faces.shape[1] < 3 or faces.dtype.kind not in "iu" or len(faces) == 0:
        raise LoosefitInputError("decompose", "faces", "(F, k >= 3) integers", f"{faces.shape}")
    if faces.min() < 0 or faces.max() >= v:
        found = f"[{faces.min()}, {faces.max()}]"
        raise LoosefitInputError("decompose", "faces", f"indices in [0, {v})", found)
    if not 1 <= cfg.bones <= v:
        raise LoosefitInputError("SSDRConfig", "bones", f"1 <= bones <= V = {v}", str(cfg.bones))
    if cfg.max_influences < 1:
        raise LoosefitInputError("SSDRConfig", "max_influences", ">= 1", str(cfg.max_influences))
    if cfg.max_frames is not None and cfg.max_frames < 1:
        raise LoosefitInputError("SSDRConfig", "max_frames", "None or >= 1", str(cfg.max_frames))
    if cfg.threads is not None and cfg.threads < 1:
        raise LoosefitInputError("SSDRConfig", "threads", "None or >= 1", str(cfg.threads))

    # 1. a seeded subset of frames bounds the cost (Dem Bones is linear in T)
    index = np.arange(t)
    if cfg.max_frames is not None and t > cfg.max_frames:
        index = np.sort(np.random.default_rng(cfg.seed).choice(t, cfg.max_frames, replace=False))
    fit = frames[index]  # (T', V, 3)
    tf = len(index)

    # 2. Dem Bones, in its layout: u (3, V), v (3 T', V), one subject
    db = DemBones()
    db.nV, db.nF, db.nS, db.nB = v, tf, 1, cfg.bones
    db.nnz = min(cfg.max_influences, cfg.bones)
    db.nIters, db.nInitIters = cfg.iterations, cfg.init_iterations
    db.nTransIters, db.nWeightsIters = cfg.transform_iterations, cfg.weight_iterations
    db.weightsSmooth = cfg.weight_smoothness
    db.fStart = np.array([0, tf], dtype=np.int32)
    db.subjectID = np.zeros(tf, dtype=np.int32)
    db.u = np.ascontiguousarray(rest.T)
    db.v = np.ascontiguousarray(fit.transpose(0, 2, 1).reshape(3 * tf, v))
    db.fv = faces.tolist()
    with _omp_threads(cfg.threads):
        db.compute()

    # 3. back to ours: weights (B, V) -> (V, B); m (4 T', 4 B) -> (T', B, 3, 4)
    b = db.nB
    weights = np.clip(np.asarray(db.get_weights()).T, 0.0, None)  # (V, B)
    weights = (weights / weights.sum(1, keepdims=True)).astype(np.float32)
    m = np.asarray(db.m).reshape(tf, 4, b, 4).transpose(0, 2, 1, 3)  # (T', B, 4, 4)
    out = SkinningDecomposition(
        rest.astype(np.float32), weights, m[..., :3, :].astype(np.float32), 0.0, index
    )
    out.rmse = float(np.sqrt(((out.skin(out.transforms) - fit) ** 2).sum(-1).mean()))
    return out


def fit_transforms(decomp: SkinningDecomposition, frames: np.ndarray) -> np.ndarray:
    """Least-squares affine bone transforms of new frames for the decomposition's fixed weights.

    Vertices are linear in the 12 B unknowns of a frame, ``x = D X`` with the
    design matrix ``D`` (V, 4 B) shared by all frames and coordinates, so one
    least-squares solve (an SVD of ``D``) gives every frame at once; where ``D``
    is rank deficient (e.g. a flat rest mesh) the minimum-norm solution is used.
    Unlike Dem Bones' transforms these are affine, not rigid.

    Args:
        decomp: the decomposition whose rest mesh and weights are used.
        frames: (T, V, 3) vertex positions.

    Returns:
        (T, B, 3, 4) float32 transforms minimising ``|skin(A_t) - x_t|^2`` per frame.
    """
    v, b = decomp.weights.shape
    frames = _check_points(frames, "fit_transforms", "frames", (None, v, 3))
    t = len(frames)
    y = frames.transpose(1, 0, 2).reshape(v, 3 * t)  # (V, 3 T)
    x = np.linalg.lstsq(decomp.design(), y, rcond=None)[0]  # (4 B, 3 T)
    return x.reshape(b, 4, t, 3).transpose(2, 0, 3, 1).astype(np.float32)  # (T, B, 3, 4)
