"""Where and why garment vertices go deep inside the body: frames, body regions, motion.

:func:`loosefit.garment.quality.quality` says *how much* of a clip's cloth is inside the
body; this module says *where* (which frames, which body part, how deep) and what the
body does there, so a flagged clip can be traced to its cause:

1. :func:`find_penetrations`: per frame, the garment vertices inside the collider (the
   closed body mesh the simulation collided with) deeper than the tolerance, their depth
   and the body region of the closest skin (:mod:`loosefit.body.regions`).
2. :func:`~loosefit.eval.motion_signals.motion_signals`: per frame, what the motion
   does: a spin, a hand near the hips, the thighs closing, a self-intersecting pose.
3. :func:`find_events` and :func:`diagnose`: runs of frames with penetration, each
   with the motion's figures over it and the causes they point to.

A garment vertex is inside the region of the closest body face's corner with the
largest barycentric weight. Everything here is a pure function of arrays.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from dataclasses import asdict, dataclass, field

import numpy as np

from loosefit.body.regions import HANDS, BodyParts
from loosefit.errors import LoosefitInputError
from loosefit.eval.depth import body_hits
from loosefit.eval.motion_signals import MotionSignals, buried_vertices, motion_signals
from loosefit.garment.quality import PENETRATION_TOLERANCE

# Thresholds behind the causes :func:`diagnose` names.
FAST_SPIN = 2.0 * np.pi  # rad/s about the vertical: a turn a second or faster
HAND_PRESS = 0.03  # m: a hand this close to the hips, waist or thighs ...
HAND_SITE = 0.10  # m: ... and this close to the penetrating cloth presses it in
THIGHS_CLOSED = 0.01  # m: the thighs' gap below this closes on the cloth between them
FAST_SKIN = 1.5  # m/s: skin this fast over the deepest cloth outruns the contact
CONTEXT_FRAMES = 5  # an event's spin is also taken over this many frames before it


# -- 1. penetrating vertices ------------------------------------------------------------------


@dataclass
class Penetrations:
    """Garment vertices inside the body, per frame, and those deeper than the tolerance.

    The deep vertices of all frames are listed flat (N of them), ordered by frame.

    Attributes:
        tolerance: m, the depth beyond which a vertex counts.
        inside_fraction: (T,) share of the garment's vertices inside the body, any depth.
        deep_fraction: (T,) share deeper than ``tolerance``.
        max_depth: (T,) m, the deepest vertex inside (0 where none is).
        frame: (N,) int64 frame of each deep vertex.
        vertex: (N,) int64 its garment vertex index.
        depth: (N,) m, its distance to the body's surface.
        region: (N,) int64 region (index into ``BodyParts.names``) of its closest skin.
        surface: (N, 3) its closest point on the body's surface (outward = surface - vertex).
    """

    tolerance: float
    inside_fraction: np.ndarray
    deep_fraction: np.ndarray
    max_depth: np.ndarray
    frame: np.ndarray
    vertex: np.ndarray
    depth: np.ndarray
    region: np.ndarray
    surface: np.ndarray

    def at(self, t: int) -> np.ndarray:
        """(n,) indices into the flat arrays of frame ``t``'s deep vertices."""
        lo, hi = np.searchsorted(self.frame, [t, t + 1])
        return np.arange(lo, hi)


def _check_sequences(garment: np.ndarray, body: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    g = np.asarray(garment, np.float32)
    b = np.asarray(body, np.float32)
    if g.ndim != 3 or g.shape[2] != 3 or g.shape[0] < 1:
        raise LoosefitInputError("penetration", "garment", "shape (T, V, 3)", f"{g.shape}")
    if b.ndim != 3 or b.shape[0] != g.shape[0] or b.shape[2] != 3:
        raise LoosefitInputError(
            "penetration", "body", f"shape ({g.shape[0]}, Vb, 3)", f"{b.shape}"
        )
    return g, b


def find_penetrations(
    garment: np.ndarray,
    body: np.ndarray,
    parts: BodyParts,
    tolerance: float = PENETRATION_TOLERANCE,
    progress: Callable[[int, int], None] | None = None,
) -> Penetrations:
    """The garment vertices deeper inside the body's collider than ``tolerance``, per frame.

    Inside is decided by the winding number, depth is the distance to the closest point of
    the collider, as in :func:`~loosefit.garment.quality.quality` (whose
    ``penetration_fraction`` is ``deep_fraction`` here). Non-finite vertices are left out.

    Args:
        garment: (T, V, 3) garment vertices.
        body: (T, Vb, 3) the posed body, the same frames.
        parts: the collider and regions (:func:`~loosefit.body.regions.body_parts`).
        tolerance: m.
        progress: called as ``progress(done, T)`` after each frame.

    Returns:
        :class:`Penetrations`.
    """
    g, b = _check_sequences(garment, body)
    if len(parts.region) != b.shape[1]:
        raise LoosefitInputError(
            "penetration",
            "body",
            f"{len(parts.region)} vertices like the body parts",
            f"{b.shape[1]}",
        )
    T, V = g.shape[:2]
    finite = np.isfinite(g).all(-1)  # (T, V)
    hits = body_hits(np.where(finite[..., None], g, 0.0), b, parts.collider_faces)
    inside, deep, max_depth = np.zeros(T), np.zeros(T), np.zeros(T)
    rows: dict[str, list] = {k: [] for k in ("frame", "vertex", "depth", "region", "surface")}
    for t, hit in enumerate(hits):
        within = hit.inside & finite[t] & (hit.faces >= 0)
        inside[t] = within.sum() / V
        if within.any():
            max_depth[t] = hit.distance[within].max()
        k = np.flatnonzero(within & (hit.distance > tolerance))
        deep[t] = len(k) / V
        rows["frame"].append(np.full(len(k), t, np.int64))
        rows["vertex"].append(k)
        rows["depth"].append(hit.distance[k].astype(np.float64))
        rows["region"].append(
            parts.face_region(parts.collider_faces, hit.faces[k], hit.barycentric[k])
        )
        rows["surface"].append(hit.points[k].astype(np.float64))
        if progress is not None:
            progress(t + 1, T)
    return Penetrations(
        tolerance=float(tolerance),
        inside_fraction=inside,
        deep_fraction=deep,
        max_depth=max_depth,
        frame=np.concatenate(rows["frame"]),
        vertex=np.concatenate(rows["vertex"]).astype(np.int64),
        depth=np.concatenate(rows["depth"]),
        region=np.concatenate(rows["region"]).astype(np.int64),
        surface=np.concatenate(rows["surface"]).reshape(-1, 3),
    )


# -- 2. events and their causes ---------------------------------------------------------------


def find_events(flags: np.ndarray, merge_gap: int = 0) -> list[tuple[int, int]]:
    """Runs of consecutive flagged frames, as ``(start, stop)`` (stop exclusive).

    Args:
        flags: (T,) bool.
        merge_gap: runs separated by at most this many unflagged frames are one event.
    """
    f = np.asarray(flags, bool)
    if f.ndim != 1:
        raise LoosefitInputError("find_events", "flags", "shape (T,)", f"{f.shape}")
    edges = np.diff(np.concatenate([[0], f.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist()
    merged: list[tuple[int, int]] = []
    for start, stop in zip(starts, stops, strict=True):
        if merged and start - merged[-1][1] <= merge_gap:
            merged[-1] = (merged[-1][0], stop)
        else:
            merged.append((start, stop))
    return merged


@dataclass
class SelfIntersection:
    """A limb buried in the rest of the body during an event."""

    limb: str
    part: str  # the region of its deepest vertex, at ``frame``
    region: str  # the region that vertex is inside
    depth: float  # m, that vertex's depth
    max_depth: float  # m, the limb's deepest over the event
    frame: int  # the event's worst frame if the limb is buried there, else its deepest
    collides: bool  # whether the cloth collides with the limb (else it cannot trap cloth)
    site: float  # m, from its buried vertices to the worst frame's deep cloth, at ``frame``


@dataclass
class PenetrationEvent:
    """A run of frames with cloth deeper than the tolerance, and what the motion does there.

    The motion's figures are taken over the event's frames, the spin also over the
    :data:`CONTEXT_FRAMES` before them (the turn that flings the cloth in).

    Attributes:
        start, stop: frames [start, stop).
        worst_frame: the frame of the deepest vertex.
        deepest: m, that vertex's depth.
        deep_share: the largest share of the garment's vertices deeper than the tolerance
            in one frame.
        region: the region of the deepest vertex.
        regions: region -> deep vertex-frames over the event, most first.
        spin: rad/s, the largest |spin|.
        hand_hip: m, the smallest hand-hip distance, and ``hand`` which hand.
        hand_site: m, at the worst frame, that hand's distance to the deepest vertex.
        hands_collide: whether the cloth collides with the hands.
        thigh_gap: m, the smallest thigh gap.
        skin_speed: m/s, at the worst frame, the speed of the skin over the deepest vertex
            (its closest body vertex, from the frame before), and ``skin_part`` its region.
        self_intersections: the limbs buried in the body, deepest first.
        causes: what the figures point to, in words; ``notes``: what they show that cannot
            push the cloth in (a limb the cloth does not collide with, a far one).
    """

    start: int
    stop: int
    worst_frame: int
    deepest: float
    deep_share: float
    region: str
    regions: dict[str, int]
    spin: float
    hand_hip: float
    hand: str
    hand_site: float
    hands_collide: bool
    thigh_gap: float
    skin_speed: float
    skin_part: str
    self_intersections: list[SelfIntersection] = field(default_factory=list)
    causes: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def frames(self) -> int:
        return self.stop - self.start

    @property
    def self_intersecting(self) -> bool:
        """Whether a limb the cloth collides with is buried in the body."""
        return any(s.collides for s in self.self_intersections)


def _skin_speed(body: np.ndarray, t: int, point: np.ndarray, fps: float) -> tuple[int, float]:
    """The body vertex nearest ``point`` (3,) in frame ``t`` of ``body`` (T, Vb, 3) and its
    speed (m/s) from frame t - 1 (t + 1 for the first frame; 0 for a single frame)."""
    v = int(np.argmin(np.linalg.norm(body[t] - point, axis=-1)))
    if len(body) < 2:
        return v, 0.0
    other = t - 1 if t > 0 else t + 1
    return v, float(np.linalg.norm(body[t, v] - body[other, v]) * fps)


def _site_distance(points: np.ndarray, site: np.ndarray) -> float:
    """The smallest distance between ``points`` (n, 3) and ``site`` (m, 3); inf if empty."""
    if len(points) == 0 or len(site) == 0:
        return float("inf")
    return float(np.linalg.norm(points[:, None] - site[None], axis=-1).min())


def diagnose(
    pen: Penetrations,
    signals: MotionSignals,
    body: np.ndarray,
    garment: np.ndarray,
    parts: BodyParts,
    fps: float,
    *,
    merge_gap: int = 0,
    context: int = CONTEXT_FRAMES,
) -> list[PenetrationEvent]:
    """The events of a clip (runs of frames with deep vertices), in order of time.

    Args:
        pen: :func:`find_penetrations` of the clip.
        signals: :func:`motion_signals` of the same frames.
        body: (T, Vb, 3) the posed body (for distances to the cloth at the worst frame).
        garment: (T, V, 3) the garment.
        parts: :func:`~loosefit.body.regions.body_parts`.
        fps: frames per second (for the skin's speed).
        merge_gap: see :func:`find_events`.
        context: frames before an event whose spin counts as its own.

    Returns:
        :class:`PenetrationEvent` list.
    """
    T = len(pen.deep_fraction)
    if len(signals.spin) != T or len(body) != T or len(garment) != T:
        raise LoosefitInputError(
            "diagnose",
            "signals, body, garment",
            f"{T} frames each",
            f"{len(signals.spin)}, {len(body)}, {len(garment)}",
        )
    events = []
    for start, stop in find_events(pen.deep_fraction > 0, merge_gap):
        rows = np.flatnonzero((pen.frame >= start) & (pen.frame < stop))
        k = rows[np.argmax(pen.depth[rows])]
        worst = int(pen.frame[k])
        deep = pen.vertex[pen.at(worst)]  # the worst frame's deep garment vertices
        hand_hip = signals.hand_hip[start:stop]  # (n, 2)
        side = int(np.argmin(hand_hip.min(axis=0)))
        hand = parts.hand_vertices[side]
        skin, speed = _skin_speed(body, worst, pen.surface[k], fps)
        selfs = []
        for j, limb in enumerate(signals.limbs):
            if signals.self_count[start:stop, j].max(initial=0) == 0:
                continue
            t = start + int(np.argmax(signals.self_depth[start:stop, j]))
            if signals.self_count[worst, j] > 0:
                t = worst  # where the cloth is deepest, if the limb is buried there too
            v = signals.self_vertex[t, j]
            buried = buried_vertices(parts, limb, body[t], signals.self_tolerance)
            selfs.append(
                SelfIntersection(
                    limb,
                    parts.names[parts.region[v]],
                    parts.names[signals.self_region[t, j]],
                    float(signals.self_depth[t, j]),
                    float(signals.self_depth[start:stop, j].max()),
                    t,
                    signals.limb_collides[j],
                    _site_distance(body[t, buried], garment[t, deep]),
                )
            )
        event = PenetrationEvent(
            start=start,
            stop=stop,
            worst_frame=worst,
            deepest=float(pen.depth[k]),
            deep_share=float(pen.deep_fraction[start:stop].max()),
            region=parts.names[pen.region[k]],
            regions=dict(Counter(parts.names[r] for r in pen.region[rows]).most_common()),
            spin=float(np.abs(signals.spin[max(start - context, 0) : stop]).max()),
            hand_hip=float(hand_hip[:, side].min()),
            hand=HANDS[side],
            hand_site=_site_distance(body[worst, hand], garment[worst, deep]),
            hands_collide=parts.collides(hand),
            thigh_gap=float(signals.thigh_gap[start:stop].min()),
            skin_speed=speed,
            skin_part=parts.names[parts.region[skin]],
            self_intersections=sorted(selfs, key=lambda s: (not s.collides, -s.depth)),
        )
        event.causes, event.notes = explain(event)
        events.append(event)
    return events


def explain(event: PenetrationEvent) -> tuple[list[str], list[str]]:
    """What an event's figures point to, in words: (causes, notes).

    A cause is a test that fires where it can push cloth into the body: a limb the cloth
    collides with buried in the body near the cloth (:data:`HAND_SITE`), a hand the cloth
    collides with pressing near it (:data:`HAND_PRESS`), the thighs closed
    (:data:`THIGHS_CLOSED`) on cloth inside the hips or a thigh, skin moving faster than
    :data:`FAST_SKIN` over the cloth, a spin faster than :data:`FAST_SPIN`. A note is a
    test that fires near the cloth where it cannot push it (a part the cloth does not
    collide with). No cause: "unexplained".
    """
    causes, notes = [], []
    for s in event.self_intersections:
        if s.site >= HAND_SITE:
            continue  # elsewhere on the body: in the event's figures only
        text = (
            f"self-intersecting body: the {s.part} {100 * s.depth:.1f} cm inside the "
            f"{s.region} (frame {s.frame}, {100 * s.site:.0f} cm from the deepest "
            "cloth)"
        )
        if s.collides:
            causes.append(text)
        else:
            notes.append(text + "; the cloth does not collide with it")
    if event.hand_hip < HAND_PRESS and event.hand_site < HAND_SITE:
        text = (
            f"the {event.hand} on the body ({100 * event.hand_hip:.1f} cm from the hips, "
            f"{100 * event.hand_site:.1f} cm from the deepest cloth)"
        )
        if event.hands_collide:
            causes.append(text.replace(" on the body", " pressing the cloth onto the body"))
        else:
            notes.append(text + "; the cloth does not collide with the hands")
    legs = ("hips", "left thigh", "right thigh")
    if event.thigh_gap < THIGHS_CLOSED and any(r in legs for r in event.regions):
        causes.append(f"the thighs closing on the cloth (gap {100 * event.thigh_gap:.1f} cm)")
    if event.skin_speed > FAST_SKIN:
        causes.append(
            f"the {event.skin_part} moving fast into the cloth ({event.skin_speed:.1f} m/s)"
        )
    if event.spin > FAST_SPIN:
        causes.append(f"a fast spin ({event.spin:.1f} rad/s)")
    return causes or [
        "unexplained: no spin, hand, thigh, skin speed or self-intersection test fires"
    ], notes


# -- the whole clip -----------------------------------------------------------------------------


@dataclass
class Diagnosis:
    """Everything :func:`diagnose_clip` finds in one clip."""

    penetrations: Penetrations
    signals: MotionSignals
    events: list[PenetrationEvent]
    fps: float

    def worst_frames(self, k: int) -> list[int]:
        """Up to ``k`` frames to look at: each event's worst, deepest first, then the
        deepest other frames with penetration."""
        picked = [e.worst_frame for e in sorted(self.events, key=lambda e: -e.deepest)][:k]
        pen = self.penetrations
        for t in np.argsort(-pen.max_depth, kind="stable").tolist():
            if len(picked) >= k or pen.deep_fraction[t] == 0:
                break
            if t not in picked:
                picked.append(int(t))
        return picked

    def summary(self) -> str:
        """One line: frames, share of cloth inside (mean, p99), deep share and depth at worst."""
        pen = self.penetrations
        return (
            f"{len(pen.deep_fraction)} frames; cloth inside the body: "
            f"{100 * pen.inside_fraction.mean():.2f} % of vertices on average (p99 "
            f"{100 * np.percentile(pen.inside_fraction, 99):.2f} %); deeper than "
            f"{1000 * pen.tolerance:.0f} mm: {100 * pen.deep_fraction.max():.2f} % in the "
            f"worst frame; deepest {100 * pen.max_depth.max():.2f} cm; "
            f"{len(self.events)} events"
        )

    def to_json(self) -> dict:
        """A JSON-ready summary: per-event figures and per-frame curves (lengths in m;
        None where a figure has no value, e.g. a body without hands)."""
        pen, sig = self.penetrations, self.signals
        return _json_safe(
            {
                "tolerance_m": pen.tolerance,
                "frames": len(pen.deep_fraction),
                "fps": self.fps,
                "inside_mean": float(pen.inside_fraction.mean()),
                "inside_p99": float(np.percentile(pen.inside_fraction, 99)),
                "deep_max": float(pen.deep_fraction.max()),
                "depth_max_m": float(pen.max_depth.max()),
                "events": [asdict(e) for e in self.events],
                "per_frame": {
                    "inside_fraction": pen.inside_fraction.round(5).tolist(),
                    "deep_fraction": pen.deep_fraction.round(5).tolist(),
                    "max_depth_m": pen.max_depth.round(5).tolist(),
                    "spin_rad_s": sig.spin.round(3).tolist(),
                    "hand_hip_m": sig.hand_hip.round(4).tolist(),
                    "thigh_gap_m": sig.thigh_gap.round(4).tolist(),
                    "self_depth_m": {
                        limb: sig.self_depth[:, j].round(4).tolist()
                        for j, limb in enumerate(sig.limbs)
                    },
                },
            }
        )


@dataclass
class CloseUp:
    """Where to look at one frame's deep cloth (see :func:`closeup`).

    Attributes:
        target: (3,) the body's surface over the deepest vertex.
        direction: (3,) from ``target`` towards a camera: out from the body's vertical
            axis through ``target``, 20 degrees above the horizon.
        deep: (V,) bool, the frame's garment vertices deeper than the tolerance.
        hidden: (Vb,) bool, the body vertices of the regions that cloth is inside.
        regions: those regions' names, most deep vertices first.
    """

    target: np.ndarray
    direction: np.ndarray
    deep: np.ndarray
    hidden: np.ndarray
    regions: tuple[str, ...]


def closeup(
    pen: Penetrations, parts: BodyParts, t: int, num_vertices: int, root: np.ndarray
) -> CloseUp:
    """:class:`CloseUp` of frame ``t`` of a clip with ``num_vertices`` V garment vertices,
    whose root joint is at ``root`` (3,) in that frame."""
    rows = pen.at(t)
    if len(rows) == 0:
        raise LoosefitInputError("closeup", "t", "a frame with deep cloth", f"frame {t}")
    k = rows[np.argmax(pen.depth[rows])]
    target = pen.surface[k]
    radial = (target - np.asarray(root, np.float64)) * [1.0, 1.0, 0.0]
    if np.linalg.norm(radial) < 1e-6:
        radial = np.array([0.0, -1.0, 0.0])  # on the axis: from the front
    direction = radial / np.linalg.norm(radial) + [0.0, 0.0, np.tan(np.radians(20.0))]
    deep = np.zeros(num_vertices, bool)
    deep[pen.vertex[rows]] = True
    regions = tuple(parts.names[r] for r, _ in Counter(pen.region[rows].tolist()).most_common())
    hidden = np.isin(parts.region, [parts.names.index(r) for r in regions])
    return CloseUp(target, direction / np.linalg.norm(direction), deep, hidden, regions)


def _json_safe(x):
    """``x`` with every non-finite float replaced by None (JSON has no inf or NaN)."""
    if isinstance(x, dict):
        return {k: _json_safe(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_json_safe(v) for v in x]
    if isinstance(x, float | np.floating):
        return float(x) if np.isfinite(x) else None
    return x


def format_events(events: list[PenetrationEvent], tolerance: float) -> str:
    """A plain-text table of events (lengths in cm), one line each, and their causes.

    Columns: the frames, the regions with the most deep vertex-frames, the deepest vertex,
    the largest share of vertices deeper than ``tolerance`` in a frame, the fastest spin,
    the closest hand to the hips, the narrowest thigh gap, the skin's speed over the
    deepest vertex, and whether a part the cloth collides with is buried in the body.
    """
    deep = f">{1000 * tolerance:.0f}mm"
    head = (
        f"{'frames':>11} {'region':<24} {'deepest':>7} {deep:>6} {'spin':>6} "
        f"{'hand-hip':>8} {'thighs':>6} {'skin':>5} {'self-int':>8}"
    )
    units = (
        f"{'':>11} {'':<24} {'cm':>7} {'%':>6} {'rad/s':>6} {'cm':>8} {'cm':>6} "
        f"{'m/s':>5} {'body':>8}"
    )
    lines = [head, units, "-" * len(head)]
    for e in events:
        regions = "+".join(list(e.regions)[:2])
        lines.append(
            f"{f'{e.start}-{e.stop - 1}':>11} {regions:<24} {100 * e.deepest:7.2f} "
            f"{100 * e.deep_share:6.2f} {e.spin:6.1f} {100 * e.hand_hip:8.1f} "
            f"{100 * e.thigh_gap:6.1f} {e.skin_speed:5.2f} "
            f"{'yes' if e.self_intersecting else 'no':>8}"
        )
    for e in events:
        lines.append(
            f"frames {e.start}-{e.stop - 1} (worst {e.worst_frame}): " + "; ".join(e.causes)
        )
        lines += [f"    note: {n}" for n in e.notes]
    return "\n".join(lines) if events else "no frame with cloth deeper than the tolerance"


def diagnose_clip(
    garment: np.ndarray,
    body: np.ndarray,
    root_rotations: np.ndarray,
    fps: float,
    parts: BodyParts,
    *,
    tolerance: float = PENETRATION_TOLERANCE,
    merge_gap: int = 0,
    progress: Callable[[int, int], None] | None = None,
) -> Diagnosis:
    """Penetrations, motion signals and events of one clip.

    Args:
        garment: (T, V, 3) garment vertices.
        body: (T, Vb, 3) the posed body.
        root_rotations: (T, 3, 3) the root's world rotation (a motion's ``rotations[:, 0]``).
        fps: frames per second.
        parts: :func:`~loosefit.body.regions.body_parts` (the simulation's collider).
        tolerance: m.
        merge_gap: see :func:`find_events`.
        progress: called as ``progress(done, 2 T)``: the penetrations, then the motion.
    """
    g, b = _check_sequences(garment, body)
    T = len(g)

    def step(offset: int) -> Callable[[int, int], None] | None:
        return None if progress is None else (lambda done, _: progress(offset + done, 2 * T))

    pen = find_penetrations(g, b, parts, tolerance, step(0))
    signals = motion_signals(b, root_rotations, fps, parts, progress=step(T))
    events = diagnose(pen, signals, b, g, parts, fps, merge_gap=merge_gap)
    return Diagnosis(pen, signals, events, float(fps))
