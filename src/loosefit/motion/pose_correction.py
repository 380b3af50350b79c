"""A capture pose that folds into the body, turned a few degrees out of it before simulation.

Motion capture retargeted onto anny's fuller body folds into itself: in salsa 60_02's
squat the capture's hip flexion takes the thigh 3.5 cm into the belly. Cloth caught in
that fold has no room and ends up inside one of the two skins, whatever the simulation
does (:mod:`loosefit.sim.overlap` only gives the collider flesh that yields). The
simulation's data sets therefore clean the motion first, as a motion-capture clean-up
would: :func:`unfold_motion` turns each colliding limb that is inside the rest of the body
at its root joint (the thigh at the hip, the upper arm at the shoulder), about the axis
that moves its buried skin out fastest, by the smallest angle that leaves ``clearance``
between the two, at most ``max_degrees``, eased in and out over ``ramp_seconds``.

A few degrees do not clear a deep fold: the buried skin lies next to the joint, so 60_02
needs 24-30 degrees at the hip to clear (``bench/data/pose_correction.py``). The cap keeps the
edit small, at the price of the fold that is left (60_02: 1.8 cm, which the collider's
flattening handles), and still halves the cloth pinched there. The edit moves the limb's
end: the turned leg's foot moves up to 12 cm in 60_02. It is the recorded motion of the
data set (the body the cloth met, the learned stages' input, every measure), and the
manifest records which frames were turned and by how much. Motion given to a trained
model is never edited.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
import torch

from loosefit.body.regions import BodyParts
from loosefit.errors import LoosefitInputError
from loosefit.geometry.query import ClosestPoints, Surface
from loosefit.geometry.rotations import axis_angle_to_matrix
from loosefit.types import Motion

# The joint each limb of :data:`loosefit.body.regions.LIMBS` is turned at.
LIMB_ROOTS: dict[str, str] = {
    "left leg": "LeftUpLeg",
    "right leg": "RightUpLeg",
    "left arm": "LeftArm",
    "right arm": "RightArm",
}
# m: limb skin this close to the rest of the body at the rest pose (where the limb joins
# it: the groin, the armpit) is not tested
JOIN_BAND = 0.02


@dataclass
class UnfoldConfig:
    """How a capture pose that folds into the body is corrected before simulation."""

    enabled: bool = True  # correct folding poses at all
    clearance: float = 0.01  # m aimed for between the buried skin and the rest of the body
    max_degrees: float = 10.0  # the largest turn of a limb's root joint
    ramp_seconds: float = 0.2  # a turn eases in and out over this
    steps: int = 10  # bisection steps of the angle search (resolution max_degrees / 2^steps)
    # the largest turn of a limb's root joint in a motion whose legs fold deeper than
    # deep_depth (why: docs/design/notes/unfold_config.md); None: max_degrees always
    deep_degrees: float | None = None
    deep_depth: float = 0.05  # m, how deep a fold must go for deep_degrees to apply
    deep_limbs: tuple[str, ...] = ("left leg", "right leg")  # the limbs whose folds count

    def __post_init__(self) -> None:
        src = "UnfoldConfig"
        if not isinstance(self.enabled, bool):
            raise LoosefitInputError(src, "enabled", "true or false", repr(self.enabled))
        for name in ("clearance", "max_degrees", "ramp_seconds", "deep_depth"):
            value = getattr(self, name)
            ok = isinstance(value, int | float) and not isinstance(value, bool)
            if not (ok and math.isfinite(value) and value >= 0):
                raise LoosefitInputError(src, name, "a finite number >= 0", repr(value))
        if self.max_degrees > 90:
            raise LoosefitInputError(src, "max_degrees", "at most 90", repr(self.max_degrees))
        if not (isinstance(self.steps, int) and 1 <= self.steps <= 30):
            raise LoosefitInputError(src, "steps", "an integer from 1 to 30", repr(self.steps))
        deep = self.deep_degrees
        if deep is not None and not (
            isinstance(deep, int | float)
            and not isinstance(deep, bool)
            and math.isfinite(deep)
            and self.max_degrees <= deep <= 90
        ):
            raise LoosefitInputError(
                src,
                "deep_degrees",
                f"None or a number from max_degrees ({self.max_degrees}) to 90",
                repr(deep),
            )
        self.deep_limbs = tuple(self.deep_limbs)
        unknown = [x for x in self.deep_limbs if x not in LIMB_ROOTS]
        if unknown:
            raise LoosefitInputError(
                src, "deep_limbs", f"limbs among {list(LIMB_ROOTS)}", repr(unknown)
            )


def motion_cap(config: UnfoldConfig, deepest: dict[str, float]) -> float:
    """The largest turn, in degrees, of any limb's root joint in a motion whose limbs fold at
    most ``deepest`` ({limb: m}) into the rest of the body: ``config.deep_degrees`` when a
    limb of ``config.deep_limbs`` folds deeper than ``config.deep_depth``, else
    ``config.max_degrees``."""
    if config.deep_degrees is not None and any(
        deepest.get(limb, 0.0) > config.deep_depth for limb in config.deep_limbs
    ):
        return float(config.deep_degrees)
    return float(config.max_degrees)


@dataclass
class Unfolded:
    """What :func:`unfold_motion` did.

    Attributes:
        motion: the corrected motion (the input itself where nothing folds).
        degrees: (T,) the largest turn of any limb's root joint per frame.
        depth_before: (T,) m, the deepest tested limb vertex inside the rest of the body.
        depth_after: (T,) m, the same after the turn.
    """

    motion: Motion
    degrees: np.ndarray
    depth_before: np.ndarray
    depth_after: np.ndarray

    @property
    def frames(self) -> int:
        """How many frames were turned."""
        return int((self.degrees > 0).sum())

    def stats(self) -> dict:
        """The manifest's record of the correction."""
        return {
            "unfold_frames": self.frames,
            "unfold_degrees_max": float(self.degrees.max(initial=0.0)),
            "fold_depth_before": float(self.depth_before.max(initial=0.0)),
            "fold_depth_after": float(self.depth_after.max(initial=0.0)),
        }


class LimbTest:
    """Signed distances of a limb's skin to the rest of the body (the collider with the limb
    cut away and capped), without the band where the limb joins the body.

    Args:
        device: warp device of the queries ("cpu", "cuda:0").

    Attributes:
        tested: (n,) int64 body vertices tested.
    """

    def __init__(self, parts: BodyParts, limb: str, rest: np.ndarray, device: str = "cpu") -> None:
        tested, _ = parts.tested_vertices(limb)
        self.surface = Surface(rest, parts.limb_faces[limb], device)
        self.tested = tested
        self._hint: np.ndarray | None = None  # each tested vertex's closest face last time
        sd, _ = self.signed(rest)
        self.tested = tested[sd > JOIN_BAND]
        self._hint = None

    def signed(self, body: np.ndarray) -> tuple[np.ndarray, ClosestPoints]:
        """(n,) m from each tested vertex of a posed body (Vb, 3) to the rest of it (outside
        positive; inf where the query found nothing), and the query.

        The search starts from the faces the last call found (poses a test meets come in
        sequence: frame after frame, angle after angle): the same answers, found sooner."""
        self.surface.refit(body)
        hit = self.surface.query(body[self.tested], hint=self._hint)
        self._hint = hit.faces.astype(np.int64)
        sd = np.where(hit.inside, -hit.distance, hit.distance)
        return np.where(hit.faces >= 0, sd, np.inf), hit


def world_rotations(rotations: np.ndarray, parents) -> np.ndarray:
    """(..., J, 3, 3) world rotations ``G_j = G_parent(j) @ R_j`` of local ones (..., J, 3, 3);
    ``parents`` (J,) lists every parent before its children, -1 for the root."""
    rotations = np.asarray(rotations, np.float64)
    G = np.empty_like(rotations)
    for j, p in enumerate(parents):
        G[..., j, :, :] = (
            rotations[..., j, :, :] if p < 0 else G[..., p, :, :] @ rotations[..., j, :, :]
        )
    return G


def fastest_axis(test: LimbTest, body: np.ndarray, pivot: np.ndarray, clearance: float):
    """(3,) the unit world axis about ``pivot`` (3,) along which a small turn moves the limb's
    buried skin out of the rest of the body (Vb, 3) fastest, each buried vertex weighted by
    how far it is from ``clearance`` outside: a turn ``d`` moves point ``p`` by
    ``d x (p - pivot)``, out along ``o`` by ``d . ((p - pivot) x o)``."""
    sd, hit = test.signed(body)
    buried = sd < 0
    p = body[test.tested[buried]]
    out = np.where(hit.inside[buried, None], hit.points[buried] - p, p - hit.points[buried])
    out /= np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-12)
    axis = ((clearance - sd[buried])[:, None] * np.cross(p - pivot, out)).sum(0)
    norm = np.linalg.norm(axis)
    return axis / norm if norm > 0 else np.array([1.0, 0.0, 0.0])


def ease(values: np.ndarray, radius: int) -> np.ndarray:
    """(T,) no lower than ``values`` (T,) >= 0 anywhere, easing in and out over ``radius``
    frames: the running maximum over +-radius, averaged by a raised cosine of that radius
    (every frame the window averages is at least the value at its centre)."""
    values = np.asarray(values, np.float64)
    if radius <= 0:
        return values.copy()
    T = len(values)
    padded = np.pad(values, radius)
    peak = np.max([padded[k : k + T] for k in range(2 * radius + 1)], 0)
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    w = np.cos(0.5 * np.pi * x / (radius + 1)) ** 2
    padded = np.pad(peak, radius, mode="edge")  # a motion that starts folded starts turned
    return np.sum([w[k] * padded[k : k + T] for k in range(2 * radius + 1)], 0) / w.sum()


def _clears(sd: np.ndarray, buried: np.ndarray, clearance: float) -> bool:
    """Whether the skin that was buried stands ``clearance`` out and no other is inside."""
    return bool(sd[buried].min(initial=np.inf) >= clearance and sd.min() >= 0)


def fold_depths(test: LimbTest, body: np.ndarray) -> tuple[np.ndarray, dict[int, np.ndarray]]:
    """(T,) m, how deep the limb's skin is inside the rest of the body (Vb, 3) per frame of a
    posed body (T, Vb, 3) (0 where it is not), and for each frame where it is, which tested
    vertices are: {t: (n,) bool}."""
    sds = [test.signed(b)[0] for b in body]
    depth = np.array([max(0.0, -s.min(initial=0.0)) for s in sds])
    return depth, {t: s < 0 for t, s in enumerate(sds) if (s < 0).any()}


# The fields that decide how far a folded frame may turn, and nothing else.
CAP_FIELDS = ("max_degrees", "deep_degrees", "deep_depth", "deep_limbs")


def same_correction(
    avatar, motion: Motion, parts: BodyParts, a: UnfoldConfig, b: UnfoldConfig
) -> bool:
    """Whether :func:`unfold_motion` corrects ``motion`` the same under ``a`` and ``b``,
    without running either (the angle search is most of its time).

    Every limb is turned by angles found for its folded frames up to one cap for the whole
    motion (:func:`motion_cap`). Two configurations that differ only in :data:`CAP_FIELDS`
    give the same motion when they give it the same cap, or when no limb folds at all.
    Configurations that differ in anything else are taken as different.
    """
    if not (a.enabled or b.enabled):
        return True
    if any(
        getattr(a, f.name) != getattr(b, f.name)
        for f in fields(UnfoldConfig)
        if f.name not in CAP_FIELDS
    ):
        return False
    avatar.check_motion(motion)
    rest = avatar.rest_vertices.double().cpu().numpy()
    with torch.no_grad():
        posed = avatar.pose(
            torch.from_numpy(motion.rotations), torch.from_numpy(motion.root_translation)
        )
    body = posed.vertices.double().cpu().numpy()
    deepest = {
        limb: float(fold_depths(LimbTest(parts, limb, rest), body)[0].max(initial=0.0))
        for limb in parts.limb_vertices
        if parts.limb_collides[limb]
    }
    return not any(deepest.values()) or motion_cap(a, deepest) == motion_cap(b, deepest)


def unfold_motion(
    avatar,
    motion: Motion,
    parts: BodyParts,
    config: UnfoldConfig | None = None,
    device: str = "cpu",
) -> Unfolded:
    """Turn every colliding limb that is inside the rest of the body out of it, at most
    ``config.max_degrees`` at its root joint (more in a motion with deep folds:
    :func:`motion_cap`).

    Args:
        avatar: the :class:`~loosefit.body.avatar.Avatar` the motion is on.
        motion: T frames on its skeleton.
        parts: the body's limbs (:func:`~loosefit.body.regions.body_parts` with the
            simulation's arms): the limbs the cloth collides with are tested.
        config: how (default :class:`UnfoldConfig`).
        device: warp device of its closest-point queries, most of its time ("cpu",
            "cuda:0": the simulation's, so that a GPU's data set run does not wait on it).

    Returns:
        The :class:`Unfolded` motion. Only the frames where a limb is inside the rest of the
        body, and the ``ramp_seconds`` around them, change, and only the limb's root joint.
    """
    config = config or UnfoldConfig()
    avatar.check_motion(motion)
    T, names, parents = motion.num_frames, avatar.joint_names, avatar.skeleton.parents

    def pose(rot: np.ndarray, frames: np.ndarray):
        with torch.no_grad():
            b = avatar.pose(
                torch.from_numpy(np.ascontiguousarray(rot, np.float32)),
                torch.from_numpy(motion.root_translation[frames]),
            )
        return b.vertices.double().cpu().numpy(), b.joint_poses[:, :, :3, 3].double().cpu().numpy()

    R = motion.rotations.astype(np.float64)
    rest = avatar.rest_vertices.double().cpu().numpy()
    body, joints = pose(R, np.arange(T))
    out, degrees = R.copy(), np.zeros(T)
    depth_before = np.zeros(T)
    radius = int(round(config.ramp_seconds * motion.fps))
    tests, folds = {}, {}
    for limb in (limb for limb in parts.limb_vertices if parts.limb_collides[limb]):
        if limb not in LIMB_ROOTS:
            raise LoosefitInputError(
                "unfold_motion", "parts", f"limbs among {list(LIMB_ROOTS)}", repr(limb)
            )
        tests[limb] = LimbTest(parts, limb, rest, device)
        folds[limb] = fold_depths(tests[limb], body)
        depth_before = np.maximum(depth_before, folds[limb][0])
    cap = math.radians(motion_cap(config, {k: d.max(initial=0.0) for k, (d, _) in folds.items()}))
    for limb, (_, buried) in folds.items():
        test, j = tests[limb], names.index(LIMB_ROOTS[limb])
        folded = np.array(sorted(buried), np.int64)
        if not len(folded) or cap <= 0:
            continue
        G = world_rotations(R[folded], parents)  # (n, J, 3, 3)
        axes = np.zeros((T, 3))  # each folded frame's turn axis, in the parent joint's frame
        for i, t in enumerate(folded):
            axes[t] = G[i, parents[j]].T @ fastest_axis(
                test, body[t], joints[t, j], config.clearance
            )
        # the smallest angle that clears, by bisection between 0 and the cap
        lo, hi = np.zeros(len(folded)), np.full(len(folded), cap)
        for _ in range(config.steps):
            mid = 0.5 * (lo + hi)
            r = R[folded].copy()
            r[:, j] = axis_angle_to_matrix(axes[folded] * mid[:, None]) @ r[:, j]
            v, _ = pose(r, folded)
            ok = np.array(
                [
                    _clears(test.signed(x)[0], buried[t], config.clearance)
                    for x, t in zip(v, folded, strict=True)
                ]
            )
            lo, hi = np.where(ok, lo, mid), np.where(ok, mid, hi)
        angle = np.zeros(T)
        angle[folded] = hi
        smooth = ease(angle, radius)
        # each frame's axis: the angle-weighted mean of the folded frames' around it
        weighted = np.pad(axes * angle[:, None], ((radius, radius), (0, 0)))
        axis = np.sum([weighted[k : k + T] for k in range(2 * radius + 1)], 0)
        norm = np.linalg.norm(axis, axis=1)
        f = np.flatnonzero((smooth > 0) & (norm > 0))
        turn = axis_angle_to_matrix(axis[f] / norm[f, None] * smooth[f, None])
        out[f, j] = turn.astype(np.float64) @ out[f, j]
        degrees[f] = np.maximum(degrees[f], np.degrees(smooth[f]))

    if not degrees.any():
        return Unfolded(motion, degrees, depth_before, depth_before.copy())
    fixed = Motion(
        motion.joint_names,
        out.astype(np.float32),
        motion.root_translation,
        motion.fps,
        motion.name,
        dict(motion.meta),
    )
    # only the turned frames changed: measure those again
    turned = np.flatnonzero(degrees > 0)
    body, _ = pose(out[turned], turned)
    depth_after = depth_before.copy()
    depth_after[turned] = 0.0
    for test in tests.values():
        depth = [max(0.0, -test.signed(b)[0].min(initial=0.0)) for b in body]
        depth_after[turned] = np.maximum(depth_after[turned], depth)
    return Unfolded(fixed, degrees, depth_before, depth_after)
