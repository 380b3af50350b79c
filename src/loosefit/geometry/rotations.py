"""Small numpy helpers for 3D rotations: Euler angles, quaternions, axis-angle.

Conventions:

* Matrices act on **column vectors**: ``v_rotated = R @ v``.
* Quaternions are ``(w, x, y, z)``, scalar first, unit length.
* Rotation of angle ``a`` about an axis is counter-clockwise when the axis points
  at the viewer (right-hand rule): ``Rz(90 deg)`` takes +X to +Y.
* Inputs may have any leading batch shape ``(...)``; outputs keep it.
* Computation is in float64; matrices, axis-angle vectors and quaternions come
  back as float32 (the geometry dtype of loosefit, see :mod:`loosefit.types`).
"""

from __future__ import annotations

import numpy as np

from loosefit.errors import LoosefitInputError

_AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}


def _axis_rotation(axis: str, angle_rad: np.ndarray) -> np.ndarray:
    """(...,) angles about one coordinate axis -> (..., 3, 3) float64 matrices."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    one, zero = np.ones_like(c), np.zeros_like(c)
    if axis == "X":
        rows = ((one, zero, zero), (zero, c, -s), (zero, s, c))
    elif axis == "Y":
        rows = ((c, zero, s), (zero, one, zero), (-s, zero, c))
    else:  # "Z"
        rows = ((c, -s, zero), (s, c, zero), (zero, zero, one))
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)  # (..., 3, 3)


def euler_to_matrix(
    angles_deg: np.ndarray, order: str, dtype: np.dtype | type = np.float32
) -> np.ndarray:
    """Euler angles in degrees to rotation matrices, with BVH semantics.

    For channels listed as ``Zrotation Xrotation Yrotation`` (``order="ZXY"``) with
    values ``(a0, a1, a2)``, the rotation is ``Rz(a0) @ Rx(a1) @ Ry(a2)``: intrinsic
    rotations applied in the listed order (equivalently, extrinsic in reverse).
    ``order`` may have one to three letters (a joint with fewer rotation channels)
    and may repeat a letter (proper Euler angles such as ``"ZXZ"``).

    Args:
        angles_deg: (..., K) angles in degrees, K = ``len(order)``.
        order: axis letters, e.g. ``"ZXY"``; case-insensitive.
        dtype: dtype of the result; computation is in float64 either way (pass
            ``np.float64`` to compose many rotations without rounding).

    Returns:
        (..., 3, 3) rotation matrices.
    """
    angles = np.asarray(angles_deg, dtype=np.float64)
    order = order.upper()
    if not order or any(a not in _AXIS_INDEX for a in order):
        raise LoosefitInputError(
            "euler_to_matrix",
            "order",
            "a string of axis letters X, Y, Z such as 'ZXY'",
            repr(order),
        )
    if angles.ndim < 1 or angles.shape[-1] != len(order):
        raise LoosefitInputError(
            "euler_to_matrix",
            "angles_deg",
            f"shape (..., {len(order)}) for order {order!r}",
            f"shape {angles.shape}",
        )
    rad = np.deg2rad(angles)
    out = _axis_rotation(order[0], rad[..., 0])
    for k in range(1, len(order)):
        out = out @ _axis_rotation(order[k], rad[..., k])
    return out.astype(dtype, copy=False)


def quat_to_matrix(quat: np.ndarray) -> np.ndarray:
    """Unit quaternions to rotation matrices (the input is normalised first).

    Args:
        quat: (..., 4) quaternions ``(w, x, y, z)``.

    Returns:
        (..., 3, 3) float32 rotation matrices.
    """
    q = np.asarray(quat, dtype=np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    rows = (
        (1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
        (2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
        (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)),
    )
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2).astype(np.float32)


def _matrix_to_quat_f64(matrix: np.ndarray) -> np.ndarray:
    """(..., 3, 3) -> (..., 4) float64 unit quaternions with w >= 0 (Shepperd's method)."""
    m = np.asarray(matrix, dtype=np.float64)
    m00, m01, m02 = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    m10, m11, m12 = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    m20, m21, m22 = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
    # Four candidates, each proportional to q and well conditioned when its
    # leading (diagonal) term is the largest: pick that one per matrix.
    cands = np.stack(
        [
            np.stack([1 + m00 + m11 + m22, m21 - m12, m02 - m20, m10 - m01], axis=-1),
            np.stack([m21 - m12, 1 + m00 - m11 - m22, m01 + m10, m02 + m20], axis=-1),
            np.stack([m02 - m20, m01 + m10, 1 - m00 + m11 - m22, m12 + m21], axis=-1),
            np.stack([m10 - m01, m02 + m20, m12 + m21, 1 - m00 - m11 + m22], axis=-1),
        ],
        axis=-2,
    )  # (..., 4 candidates, 4)
    diag = np.stack([cands[..., k, k] for k in range(4)], axis=-1)  # (..., 4)
    best = np.argmax(diag, axis=-1)[..., None, None]  # (..., 1, 1)
    q = np.take_along_axis(cands, np.broadcast_to(best, (*best.shape[:-2], 1, 4)), axis=-2)
    q = q[..., 0, :]  # (..., 4)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)


def matrix_to_quat(matrix: np.ndarray) -> np.ndarray:
    """Rotation matrices to unit quaternions ``(w, x, y, z)`` with ``w >= 0``.

    Args:
        matrix: (..., 3, 3) rotation matrices.

    Returns:
        (..., 4) float32 quaternions.
    """
    return _matrix_to_quat_f64(matrix).astype(np.float32)


def _slerp_f64(q0: np.ndarray, q1: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Float64 slerp; see :func:`quat_slerp`."""
    q0 = np.asarray(q0, dtype=np.float64)
    q1 = np.asarray(q1, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)[..., None]  # (..., 1)
    q0 = q0 / np.linalg.norm(q0, axis=-1, keepdims=True)
    q1 = q1 / np.linalg.norm(q1, axis=-1, keepdims=True)
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)  # (..., 1)
    q1 = np.where(dot < 0, -q1, q1)  # hemisphere: take the short way round
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin_theta = np.sin(theta)
    near = sin_theta < 1e-6  # almost the same rotation: fall back to lerp
    safe = np.where(near, 1.0, sin_theta)
    w0 = np.where(near, 1 - t, np.sin((1 - t) * theta) / safe)
    w1 = np.where(near, t, np.sin(t * theta) / safe)
    q = w0 * q0 + w1 * q1
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def quat_slerp(q0: np.ndarray, q1: np.ndarray, t: np.ndarray | float) -> np.ndarray:
    """Spherical linear interpolation of unit quaternions along the shorter arc.

    ``q1`` is negated where ``dot(q0, q1) < 0`` (hemisphere correction), so the
    result is the rotation a fraction ``t`` of the way along the minimal rotation
    from ``q0`` to ``q1``.

    Args:
        q0: (..., 4) start quaternions ``(w, x, y, z)``.
        q1: (..., 4) end quaternions.
        t: (...) or scalar interpolation fractions, 0 gives ``q0``, 1 gives ``q1``
            (up to sign).

    Returns:
        (..., 4) float32 unit quaternions.
    """
    return _slerp_f64(q0, q1, t).astype(np.float32)


def axis_angle_to_matrix(axis_angle: np.ndarray) -> np.ndarray:
    """Rotation vectors (axis times angle in radians) to matrices (Rodrigues' formula).

    Args:
        axis_angle: (..., 3) rotation vectors.

    Returns:
        (..., 3, 3) float32 rotation matrices.
    """
    v = np.asarray(axis_angle, dtype=np.float64)
    angle = np.linalg.norm(v, axis=-1)  # (...)
    half = 0.5 * angle
    # sin(half) / angle, with its limit 1/2 at angle -> 0
    small = angle < 1e-8
    scale = np.where(small, 0.5 - angle**2 / 48.0, np.sin(half) / np.where(small, 1.0, angle))
    q = np.concatenate([np.cos(half)[..., None], v * scale[..., None]], axis=-1)  # (..., 4)
    return quat_to_matrix(q)


def matrix_to_axis_angle(matrix: np.ndarray) -> np.ndarray:
    """Rotation matrices to rotation vectors, angles in ``[0, pi]``.

    Args:
        matrix: (..., 3, 3) rotation matrices.

    Returns:
        (..., 3) float32 rotation vectors (unit axis times angle in radians).
    """
    q = _matrix_to_quat_f64(matrix)  # w >= 0
    w, v = q[..., 0], q[..., 1:]
    n = np.linalg.norm(v, axis=-1)  # sin(angle / 2)
    angle = 2.0 * np.arctan2(n, w)
    small = n < 1e-8
    scale = np.where(small, 2.0 / np.maximum(w, 1e-12), angle / np.where(small, 1.0, n))
    return (v * scale[..., None]).astype(np.float32)


def rotation_angle(r0: np.ndarray, r1: np.ndarray) -> np.ndarray:
    """Angle of the relative rotation ``r0^T @ r1``: the geodesic distance on SO(3).

    Args:
        r0: (..., 3, 3) rotation matrices.
        r1: (..., 3, 3) rotation matrices.

    Returns:
        (...) float64 angles in radians, in ``[0, pi]``.
    """
    rel = np.swapaxes(np.asarray(r0, np.float64), -1, -2) @ np.asarray(r1, np.float64)
    q = _matrix_to_quat_f64(rel)
    return 2.0 * np.arctan2(np.linalg.norm(q[..., 1:], axis=-1), q[..., 0])


def rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The minimal rotation taking direction ``a`` to direction ``b``.

    The rotation is about ``a x b``. When ``a`` and ``b`` are antiparallel the axis
    is not unique: a half turn about an axis perpendicular to ``a`` is returned
    (the one perpendicular to ``a`` and to the coordinate axis least aligned with it).

    Args:
        a: (..., 3) non-zero vectors (need not be unit).
        b: (..., 3) non-zero vectors, broadcastable against ``a``.

    Returns:
        (..., 3, 3) float32 rotation matrices ``R`` with ``R @ a_hat = b_hat``.

    Raises:
        LoosefitInputError: if a vector has zero length or is not finite.
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    a, b = np.broadcast_arrays(a, b)
    for name, v in (("a", a), ("b", b)):
        if v.ndim < 1 or v.shape[-1] != 3:
            raise LoosefitInputError("rotation_between", name, "shape (..., 3)", f"{v.shape}")
        n = np.linalg.norm(v, axis=-1)
        if not np.all(np.isfinite(n)) or np.any(n < 1e-12):
            raise LoosefitInputError(
                "rotation_between", name, "finite non-zero vectors", "a zero or non-finite vector"
            )
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    c = np.sum(a * b, axis=-1, keepdims=True)  # (..., 1) cos of the angle
    # q = (1 + cos, a x b), normalised, is the half-angle quaternion of the minimal rotation.
    q = np.concatenate([1.0 + c, np.cross(a, b)], axis=-1)  # (..., 4)
    # Antiparallel: pick an axis perpendicular to a, half turn about it.
    least = np.argmin(np.abs(a), axis=-1)  # (...)
    helper = np.eye(3)[least]  # (..., 3)
    perp = np.cross(a, helper)
    perp = perp / np.linalg.norm(perp, axis=-1, keepdims=True)
    flip = np.concatenate([np.zeros_like(c), perp], axis=-1)
    q = np.where(1.0 + c < 1e-12, flip, q)
    return quat_to_matrix(q)
