"""Left-right mirrored motions: the same dance danced the other way round.

A symmetric garment on a symmetric body gives, for a mirrored motion, the
mirrored simulation: twice the training motions for the price of simulating
them (data augmentation), and a test that a model has not learned a side.

The avatar's reference pose faces -Y with Z up, so its plane of symmetry is
X = 0. With ``S = diag(-1, 1, 1)`` and ``sigma`` the permutation that swaps
each left joint with its right twin, the mirrored world rotations are
``G'_j = S G_sigma(j) S``; because ``sigma`` maps parents to parents, the local
rotations transform alike, ``R'_j = S R_sigma(j) S``, and the root moves to
``S p``.
"""

from __future__ import annotations

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.types import Motion

REFLECT = np.diag([-1.0, 1.0, 1.0]).astype(np.float32)  # X = 0, the avatar's plane of symmetry
SIDES = (("Left", "Right"), ("L", "R"))  # CMU: LeftUpLeg / RightUpLeg, LHipJoint / RHipJoint


def twin(name: str) -> str | None:
    """The joint on the other side (``LeftArm`` -> ``RightArm``); None for a central joint."""
    for left, right in SIDES:
        for a, b in ((left, right), (right, left)):
            if name.startswith(a) and len(name) > len(a) and name[len(a)].isupper():
                return b + name[len(a) :]
    return None


def mirror_permutation(joint_names: tuple[str, ...]) -> np.ndarray:
    """(J,) for each joint, the index of its twin (itself for a central joint).

    Raises:
        LoosefitInputError: a sided joint whose twin is not in the skeleton.
    """
    index = {n: i for i, n in enumerate(joint_names)}
    perm = np.arange(len(joint_names))
    for i, name in enumerate(joint_names):
        other = twin(name)
        if other is None:
            continue
        if other not in index:
            raise LoosefitInputError(
                "motion",
                "joint_names",
                f"'{other}', the twin of '{name}' (to mirror the motion)",
                "no such joint",
            )
        perm[i] = index[other]
    return perm


def mirror_motion(motion: Motion) -> Motion:
    """The motion reflected in the avatar's plane of symmetry (X = 0), left and right swapped.

    Args:
        motion: T frames on a skeleton whose sided joints come in twins.

    Returns:
        A new :class:`Motion` of the same length, joints and rate, named ``mirror:NAME``.
    """
    perm = mirror_permutation(motion.joint_names)
    rotations = REFLECT @ motion.rotations[:, perm] @ REFLECT  # (T, J, 3, 3)
    root = motion.root_translation @ REFLECT  # (T, 3); REFLECT is symmetric
    meta = {**motion.meta, "mirrored": not motion.meta.get("mirrored", False)}
    return Motion(motion.joint_names, rotations, root, motion.fps, f"mirror:{motion.name}", meta)


def vertex_twins(vertices: np.ndarray, tolerance: float = 1e-3) -> np.ndarray:
    """(V,) for each vertex of a mirror-symmetric mesh, the index of its mirror image.

    Args:
        vertices: (V, 3) a garment in the avatar's frame (symmetric about X = 0).
        tolerance: metres a mirrored vertex may lie from its twin.

    Raises:
        LoosefitInputError: the mesh is not symmetric to within ``tolerance``.
    """
    v = np.asarray(vertices, dtype=np.float64)
    reflected = v @ REFLECT.astype(np.float64)
    d2 = (reflected**2).sum(1)[:, None] - 2 * reflected @ v.T + (v**2).sum(1)[None]  # (V, V)
    twins = d2.argmin(1)
    worst = float(np.sqrt(max(d2[np.arange(len(v)), twins].max(), 0.0)))
    if worst > tolerance or len(np.unique(twins)) != len(v):
        expected = f"a mesh symmetric about X = 0 to {tolerance * 1000:.1f} mm (to mirror it)"
        found = f"a vertex {worst * 1000:.1f} mm from any mirror image"
        raise LoosefitInputError("garment", "vertices", expected, found)
    return twins


def mirror_garment(vertices: np.ndarray, twins: np.ndarray) -> np.ndarray:
    """(..., V, 3) garment positions mirrored about X = 0, each vertex onto its twin's place."""
    return (np.asarray(vertices) @ REFLECT)[..., twins, :]
