"""Rotation helpers against analytic answers."""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.geometry.rotations import (
    axis_angle_to_matrix,
    euler_to_matrix,
    matrix_to_axis_angle,
    matrix_to_quat,
    quat_slerp,
    quat_to_matrix,
    rotation_angle,
    rotation_between,
)

EX, EY, EZ = np.eye(3)

# 90 degrees about each axis, column vectors: Rx takes y to z, Ry takes z to x, Rz takes x to y.
RX90 = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], dtype=float)
RY90 = np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0]], dtype=float)
RZ90 = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]], dtype=float)
S = np.sqrt(0.5)


def random_rotations(n: int, seed: int = 0) -> np.ndarray:
    q = np.random.default_rng(seed).normal(size=(n, 4))
    return quat_to_matrix(q)


@pytest.mark.parametrize(
    ("order", "angles", "expected"),
    [
        ("X", [90], RX90),
        ("Y", [90], RY90),
        ("Z", [90], RZ90),
        ("ZXY", [90, 0, 0], RZ90),
        ("ZXY", [0, 90, 0], RX90),
        ("ZXY", [0, 0, 90], RY90),
        # Intrinsic, in listed order: R = R_first @ R_second.
        ("ZX", [90, 90], RZ90 @ RX90),
        ("XZ", [90, 90], RX90 @ RZ90),
        ("ZYX", [90, 90, 90], RZ90 @ RY90 @ RX90),
    ],
)
def test_euler_to_matrix_quarter_turns(order, angles, expected):
    np.testing.assert_allclose(euler_to_matrix(np.array(angles), order), expected, atol=1e-6)


def test_euler_order_matters_on_vectors():
    # Rz(90) Rx(90) e_x: Rx keeps e_x, Rz takes it to e_y.
    np.testing.assert_allclose(euler_to_matrix([90, 90], "ZX") @ EX, EY, atol=1e-6)
    # Rx(90) Rz(90) e_x: Rz takes e_x to e_y, Rx takes e_y to e_z.
    np.testing.assert_allclose(euler_to_matrix([90, 90], "XZ") @ EX, EZ, atol=1e-6)


def test_euler_batch_shape_and_dtype():
    out = euler_to_matrix(np.zeros((5, 4, 3)), "zxy")
    assert out.shape == (5, 4, 3, 3) and out.dtype == np.float32
    assert euler_to_matrix(np.zeros(3), "XYZ", dtype=np.float64).dtype == np.float64


def test_euler_bad_input():
    with pytest.raises(LoosefitInputError, match="order"):
        euler_to_matrix(np.zeros(3), "XQZ")
    with pytest.raises(LoosefitInputError, match="angles_deg"):
        euler_to_matrix(np.zeros(2), "XYZ")


def test_quat_to_matrix_quarter_turns():
    np.testing.assert_allclose(quat_to_matrix([S, S, 0, 0]), RX90, atol=1e-6)
    np.testing.assert_allclose(quat_to_matrix([S, 0, S, 0]), RY90, atol=1e-6)
    np.testing.assert_allclose(quat_to_matrix([S, 0, 0, S]), RZ90, atol=1e-6)
    np.testing.assert_allclose(quat_to_matrix([2.0, 0, 0, 0]), np.eye(3), atol=1e-6)


def test_matrix_to_quat_round_trip():
    r = random_rotations(200)
    q = matrix_to_quat(r)
    assert (q[:, 0] >= 0).all()
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-6)
    np.testing.assert_allclose(quat_to_matrix(q), r, atol=1e-5)
    # Half turns (w = 0) are where naive formulas break.
    for axis in np.eye(3):
        half = axis_angle_to_matrix(np.pi * axis)
        np.testing.assert_allclose(quat_to_matrix(matrix_to_quat(half)), half, atol=1e-6)


def test_axis_angle_quarter_turns_and_round_trip():
    np.testing.assert_allclose(axis_angle_to_matrix(np.pi / 2 * EX), RX90, atol=1e-6)
    np.testing.assert_allclose(axis_angle_to_matrix(np.pi / 2 * EY), RY90, atol=1e-6)
    np.testing.assert_allclose(axis_angle_to_matrix(np.pi / 2 * EZ), RZ90, atol=1e-6)
    np.testing.assert_allclose(axis_angle_to_matrix(np.zeros(3)), np.eye(3), atol=1e-7)
    np.testing.assert_allclose(matrix_to_axis_angle(RZ90), [0, 0, np.pi / 2], atol=1e-6)
    np.testing.assert_allclose(matrix_to_axis_angle(np.eye(3)), [0, 0, 0], atol=1e-7)
    v = np.random.default_rng(1).normal(size=(100, 3))
    v *= (np.random.default_rng(2).uniform(1e-6, 3.0, size=100) / np.linalg.norm(v, axis=1))[
        :, None
    ]
    np.testing.assert_allclose(matrix_to_axis_angle(axis_angle_to_matrix(v)), v, atol=1e-5)


def test_slerp_midpoint_and_ends():
    q0 = np.array([1.0, 0, 0, 0])
    q1 = matrix_to_quat(RZ90)
    mid = quat_slerp(q0, q1, 0.5)
    expected = [np.cos(np.pi / 8), 0, 0, np.sin(np.pi / 8)]  # 45 degrees about z
    np.testing.assert_allclose(mid, expected, atol=1e-6)
    np.testing.assert_allclose(quat_slerp(q0, q1, 0.0), q0, atol=1e-6)
    np.testing.assert_allclose(quat_slerp(q0, q1, 1.0), q1, atol=1e-6)
    # Constant angular speed: t = 1/3 of a 90-degree turn is 30 degrees.
    third = quat_to_matrix(quat_slerp(q0, q1, 1 / 3))
    np.testing.assert_allclose(third, euler_to_matrix([30], "Z"), atol=1e-6)


def test_slerp_hemisphere_correction():
    q0 = np.array([1.0, 0, 0, 0])
    q1 = -matrix_to_quat(RZ90)  # same rotation, other hemisphere
    mid = quat_to_matrix(quat_slerp(q0, q1, 0.5))
    np.testing.assert_allclose(mid, euler_to_matrix([45], "Z"), atol=1e-6)


def test_slerp_batch_and_identical_inputs():
    q = matrix_to_quat(random_rotations(10))
    out = quat_slerp(q, q, np.linspace(0, 1, 10))
    np.testing.assert_allclose(np.abs(np.sum(out * q, axis=-1)), 1.0, atol=1e-6)


def test_rotation_angle():
    np.testing.assert_allclose(rotation_angle(np.eye(3), RZ90), np.pi / 2, atol=1e-7)
    np.testing.assert_allclose(rotation_angle(RX90, RX90), 0.0, atol=1e-7)
    small = euler_to_matrix([0.01], "Y", dtype=np.float64)
    np.testing.assert_allclose(rotation_angle(np.eye(3), small), np.deg2rad(0.01), rtol=1e-6)


@pytest.mark.parametrize(
    ("a", "b", "expected"),
    [
        (EX, EY, RZ90),
        (EY, EZ, RX90),
        (EZ, EX, RY90),
        (2 * EX, 5 * EX, np.eye(3)),  # lengths do not matter
    ],
)
def test_rotation_between_analytic(a, b, expected):
    np.testing.assert_allclose(rotation_between(a, b), expected, atol=1e-6)


def test_rotation_between_antiparallel_and_batch():
    a = np.array([EX, EY, [1.0, 2.0, 3.0], [0.3, -0.2, 0.9]])
    b = -a
    r = rotation_between(a, b)
    a_hat = a / np.linalg.norm(a, axis=1, keepdims=True)
    np.testing.assert_allclose((r @ a_hat[..., None])[..., 0], -a_hat, atol=1e-6)
    np.testing.assert_allclose(rotation_angle(np.eye(3), r), np.pi, atol=1e-6)
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-6)
    # General directions: R a = b and the angle is the angle between them.
    rng = np.random.default_rng(3)
    a, b = rng.normal(size=(2, 50, 3))
    r = rotation_between(a, b)
    a_hat = a / np.linalg.norm(a, axis=1, keepdims=True)
    b_hat = b / np.linalg.norm(b, axis=1, keepdims=True)
    np.testing.assert_allclose((r @ a_hat[..., None])[..., 0], b_hat, atol=1e-5)
    angle = np.arccos(np.clip(np.sum(a_hat * b_hat, axis=1), -1, 1))
    np.testing.assert_allclose(rotation_angle(np.eye(3), r), angle, atol=1e-5)


def test_rotation_between_zero_vector():
    with pytest.raises(LoosefitInputError, match="rotation_between"):
        rotation_between(np.zeros(3), EX)
