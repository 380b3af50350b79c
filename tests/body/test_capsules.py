"""Capsules fitted to a body: the distance to a segment against hand-worked points, and the
fit on a synthetic body whose every capsule is a cylinder of a known radius."""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.body.capsules import CAPSULE_SPECS, Capsule, fit_capsules, segment_distance


def test_distance_to_a_segment_and_where_along_it():
    a, b = np.zeros(3), np.array([2.0, 0, 0])
    points = np.array([[1.0, 1.0, 0], [-1.0, 0, 0], [3.0, 0, 4.0], [0.5, 0, -0.25]])
    d, t = segment_distance(points, a, b)
    np.testing.assert_allclose(d, [1.0, 1.0, np.hypot(1, 4), 0.25])
    np.testing.assert_allclose(t, [0.5, -0.5, 1.5, 0.25])  # before clipping
    d, t = segment_distance(points[:1], a, a)  # a point segment: the distance to the point
    np.testing.assert_allclose(d, [np.sqrt(2)])


# a skeleton standing along +Z: each joint's name and its head (rest position, m)
SKELETON = {
    "Hips": (0, 0, 1.0),
    "LHipJoint": (0.05, 0, 0.95),
    "RHipJoint": (-0.05, 0, 0.95),
    "LowerBack": (0, 0, 1.05),
    "Spine": (0, 0, 1.15),
    "Spine1": (0, 0, 1.3),
    "LeftUpLeg": (0.1, 0, 0.9),
    "LeftLeg": (0.1, 0, 0.5),
    "LeftFoot": (0.1, 0, 0.08),
    "RightUpLeg": (-0.1, 0, 0.9),
    "RightLeg": (-0.1, 0, 0.5),
    "RightFoot": (-0.1, 0, 0.08),
}
JOINTS = tuple(SKELETON)
HEADS = np.array(list(SKELETON.values()), float)


def _cylinder(a: np.ndarray, b: np.ndarray, r: float, n: int = 40) -> np.ndarray:
    """Points on the side of the cylinder of axis a-b and radius r."""
    axis = (b - a) / np.linalg.norm(b - a)
    u = np.cross(axis, [0.0, 1.0, 0.0] if abs(axis[1]) < 0.9 else [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(axis, u)
    s, ang = np.meshgrid(np.linspace(0.05, 0.95, 8), np.linspace(0, 2 * np.pi, n // 8, False))
    return (
        a
        + s.reshape(-1, 1) * (b - a)
        + r * (np.cos(ang).reshape(-1, 1) * u + np.sin(ang).reshape(-1, 1) * w)
    )


def test_each_capsule_is_fitted_to_its_bones_vertices():
    radius = {"pelvis": 0.15, "abdomen": 0.13, "waist": 0.12, "left_shin": 0.05}
    head = dict(zip(JOINTS, HEADS, strict=True))
    verts, bones = [], []
    for name in ("pelvis", "abdomen", "waist", "left_shin"):
        joint, own, s, e = CAPSULE_SPECS[name]
        ring = _cylinder(head[s], head[e], radius[name])
        verts.append(ring)
        bones.append(np.full(len(ring), JOINTS.index(own[-1])))
    # the left thigh's two capsules share its vertices: a cylinder along the whole thigh
    thigh = _cylinder(head["LeftUpLeg"], head["LeftLeg"], 0.08)
    verts.append(thigh)
    bones.append(np.full(len(thigh), JOINTS.index("LeftUpLeg")))
    for a, b, r in (("RightUpLeg", "RightLeg", 0.07), ("RightLeg", "RightFoot", 0.045)):
        ring = _cylinder(head[a], head[b], r)  # the right leg: a thinner one
        verts.append(ring)
        bones.append(np.full(len(ring), JOINTS.index(a)))
    caps = {
        c.name: c for c in fit_capsules(JOINTS, HEADS, np.concatenate(verts), np.concatenate(bones))
    }
    assert list(caps) == list(CAPSULE_SPECS)
    thighs = {"left_thigh_upper": 0.08, "left_thigh_lower": 0.08}
    thighs |= {"right_thigh_upper": 0.07, "right_thigh_lower": 0.07, "right_shin": 0.045}
    want = {**radius, **thighs}
    for name, r in want.items():
        assert caps[name].radius == pytest.approx(r, abs=1e-9), name
    # points in the joint's frame: the thigh's lower capsule from the thigh's middle to the knee
    low = caps["left_thigh_lower"]
    assert low.joint == "LeftUpLeg"
    np.testing.assert_allclose(low.start, [0, 0, -0.2], atol=1e-12)
    np.testing.assert_allclose(low.end, [0, 0, -0.4], atol=1e-12)
    np.testing.assert_allclose(caps["pelvis"].start, [0.1, 0, -0.1], atol=1e-12)
    as_dict = Capsule("x", "Hips", (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), 0.2).to_dict()
    assert as_dict == {
        "name": "x",
        "joint": "Hips",
        "start": [0.0, 0.0, 0.0],
        "end": [1.0, 0.0, 0.0],
        "radius": 0.2,
    }
