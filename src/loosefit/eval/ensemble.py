"""Dynamics judged against an ensemble: the same motion simulated several times from
different seeds (members), and a prediction scored against all of them.

Cloth is chaotic: one clip simulated again from a start jittered by 0.1 mm ends
centimetres away. A deterministic model fitted to one simulation learns an average, which
swings less than any member; RMSE against one member cannot tell a good swing from a mean
drape. The measures here treat the members as samples of what the cloth may do:

- :func:`spread`: each member against each other member (the chaos floor);
- :func:`rmse_to_mean`: against the members' vertex-wise mean;
- :func:`energy_score`: a proper score of the model's samples against each member taken as
  the observation; it rewards the right spread and does not reward a mean;
- :func:`~loosefit.eval.hem.hem_flare`, :func:`~loosefit.eval.hem.hem_speed` and
  :func:`inside_band`: the hem's swing against the members' range frame by frame, and
  :func:`band_gap` how far outside it;
- :func:`cloth_in_front`: whether the skirt covers a raised knee.

Members are gathered from one or several data sets and checked to be of the same garment,
avatar, cloth configuration and motion in :mod:`loosefit.eval.ensemble_members`
(:func:`~loosefit.eval.ensemble_members.gather_ensembles`). Every measure here is a pure
function of arrays.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.eval.ensemble_members import gather_ensembles
from loosefit.eval.hem import hem_flare, hem_speed
from loosefit.eval.metrics import rmse, rmse_per_frame

TURN_WINDOW = 30  # frames either side of the fastest turn (61 in all)
SECTION = "## Against an ensemble of simulations"  # the ensemble's section of a results page


# --------------------------------------------------------------------------- measures


def pairwise_rmse(members: np.ndarray) -> np.ndarray:
    """(M, T, V, 3) -> (M(M-1)/2, T): every pair of members' per-frame RMS distance (m)."""
    M = len(members)
    if M < 2:
        raise LoosefitInputError(
            "ensemble",
            "members",
            "at least two members for a spread",
            f"{M}",
            hint="simulate the clip again from other seeds (loosefit simulate --seeds 0,1,2,3) "
            "or pass more data sets of the same clips",
        )
    return np.stack(
        [rmse_per_frame(members[i], members[j]) for i in range(M) for j in range(i + 1, M)]
    )


def rmse_to_mean(pred: np.ndarray, members: np.ndarray) -> np.ndarray:
    """(T, V, 3), (M, T, V, 3) -> (T,): the prediction against the members' vertex-wise mean."""
    return rmse_per_frame(pred, np.asarray(members, np.float64).mean(0))


def rmse_to_members(pred: np.ndarray, members: np.ndarray) -> np.ndarray:
    """(T, V, 3), (M, T, V, 3) -> (M,): the prediction's RMSE over the clip against each member."""
    return np.array([rmse(pred, m) for m in members])


def energy_score(samples: np.ndarray, members: np.ndarray) -> np.ndarray:
    """The energy score of a model's samples against each member, per frame.

    With S samples X_1..X_S of the model (S = 1 for a deterministic one) and a member y as
    the observation, ``ES = mean_i d(X_i, y) - 1/2 mean_ij d(X_i, X_j)``, d the frame's RMS
    vertex distance; averaged over the members. Lower is better; a proper score: its
    expectation is lowest when the samples are drawn as the observations are, so it rewards
    the right spread and does not reward a mean.

    Args:
        samples: (S, T, V, 3) the model's realisations of one clip.
        members: (M, T, V, 3) the simulations of it.

    Returns:
        (T,) metres.
    """
    samples = np.asarray(samples)
    S = len(samples)
    fit = np.mean([rmse_per_frame(x, y) for x in samples for y in members], axis=0)
    if S == 1:
        return fit
    # mean over all ordered pairs i, j (i == j counts 0): 2 / S^2 of the unordered sum
    spread = np.zeros(samples.shape[1])
    for i in range(S):
        for j in range(i + 1, S):
            spread += 2 * rmse_per_frame(samples[i], samples[j])
    return fit - 0.5 * spread / S**2


def members_energy_score(members: np.ndarray) -> np.ndarray:
    """(M, T, V, 3) -> (T,): the simulation's own energy score, each member scored as the
    observation against the others taken as samples (leave one out), averaged: what a model
    as good as the simulation would score (its samples fewer by one)."""
    M = len(members)
    if M < 3:
        raise LoosefitInputError(
            "ensemble",
            "members",
            "at least three members for the simulation's own score",
            f"{M}",
            hint="simulate the clip again from other seeds (loosefit simulate --seeds)",
        )
    return np.mean(
        [energy_score(np.delete(members, k, axis=0), members[k : k + 1]) for k in range(M)], axis=0
    )


def inside_band(series: np.ndarray, band: np.ndarray) -> np.ndarray:
    """(T,), (M, T) -> (T,) bool: the series between the members' lowest and highest."""
    band = np.asarray(band)
    return (series >= band.min(0)) & (series <= band.max(0))


def band_gap(series: np.ndarray, band: np.ndarray) -> np.ndarray:
    """(T,), (M, T) -> (T,): how far the series lies outside the members' range, frame by
    frame (0 inside it): how near a miss is, where :func:`inside_band` says only whether."""
    band = np.asarray(band)
    series = np.asarray(series)
    return np.maximum(band.min(0) - series, 0.0) + np.maximum(series - band.max(0), 0.0)


def turn_window(frame: int, frames: int, half: int = TURN_WINDOW) -> slice:
    """The frames within ``half`` of ``frame`` (61 in all away from the clip's ends)."""
    return slice(max(frame - half, 0), min(frame + half + 1, frames))


def _ray_hits(
    origin: np.ndarray, direction: np.ndarray, vertices: np.ndarray, faces: np.ndarray
) -> np.ndarray:
    """Distances along a ray (t > 0) at which it crosses a triangle mesh (Moller-Trumbore)."""
    a, b, c = (np.asarray(vertices, np.float64)[np.asarray(faces)[:, k]] for k in range(3))
    e1, e2 = b - a, c - a
    p = np.cross(direction, e2)
    det = (e1 * p).sum(-1)
    ok = np.abs(det) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = origin - a
    u = (s * p).sum(-1) * inv
    q = np.cross(s, e1)
    v = (direction * q).sum(-1) * inv
    t = (e2 * q).sum(-1) * inv
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    return np.sort(t[hit])


def cloth_in_front(
    knee: np.ndarray,
    pelvis: np.ndarray,
    garment: np.ndarray,
    garment_faces: np.ndarray,
    body: np.ndarray,
    body_faces: np.ndarray,
    *,
    tolerance: float = 0.005,
) -> bool:
    """Whether the skirt lies in front of a raised knee: the ray from the knee joint out,
    horizontally away from the pelvis's vertical axis, meets the skirt no nearer than it
    leaves the knee's skin (less ``tolerance``, m). A knee through the skirt has the skirt
    behind its skin on that ray, or none on it.

    Args:
        knee, pelvis: (3,) joint positions (+Z up).
        garment: (V, 3), garment_faces (F, 3): the skirt at that frame.
        body: (Vb, 3), body_faces (Fb, 3): the body at that frame.
    """
    out = np.asarray(knee, np.float64) - np.asarray(pelvis, np.float64)
    out[2] = 0.0
    n = np.linalg.norm(out)
    if n < 1e-6:
        return False
    out /= n
    skin = _ray_hits(np.asarray(knee, np.float64), out, body, body_faces)
    cloth = _ray_hits(np.asarray(knee, np.float64), out, garment, garment_faces)
    leave = skin[0] if len(skin) else 0.0
    return bool(len(cloth) and cloth[-1] >= leave - tolerance)


KNEE_LIFT = 0.10  # m: a knee this much above the other is raised (a leg the skirt must cover)


@dataclass
class ClipContext:
    """What the ensemble measures need of a clip's motion, on ``frames`` frames.

    Attributes:
        pelvis: (T, 3) the root joint's world position.
        hem: (H,) the garment's hem ring.
        faces: (F, 3) the garment's triangles.
        fps: the motion's frame rate.
        turn: the frame of the fastest turn; turn_rate: its rad/s.
        knee_frames: the frames where a knee is raised (:data:`KNEE_LIFT` above the other)
            and still below the pelvis, where the skirt has to cover it.
        leg: of those, the frame where the raised knee is highest (None: no raised knee);
            leg_height: how far above the other knee (m).
        covers: ``covers(garment (V, 3), t) -> bool``: the skirt at frame ``t`` (one of
            ``knee_frames``) lies in front of the raised knee (:func:`cloth_in_front`).
    """

    pelvis: np.ndarray
    hem: np.ndarray
    faces: np.ndarray
    fps: float
    turn: int
    turn_rate: float
    knee_frames: list[int]
    leg: int | None
    leg_height: float
    covers: object


def raised_knees(knees: np.ndarray, pelvis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Frames with a raised knee under the pelvis, and which knee.

    Args:
        knees: (T, 2, 3) the left and right knee joints; pelvis: (T, 3).

    Returns:
        (K,) the frames, in order; (K,) the raised knee of each (0 left, 1 right).
    """
    z = knees[..., 2]
    up = np.argmax(z, axis=1)
    lift = np.abs(z[:, 0] - z[:, 1])
    under = z[np.arange(len(z)), up] < pelvis[:, 2]
    frames = np.flatnonzero((lift >= KNEE_LIFT) & under)
    return frames, up[frames]


def clip_context(seq, frames: int, avatar) -> ClipContext:
    """The :class:`ClipContext` of a sequence's first ``frames`` frames on ``avatar`` (the
    body it was simulated on, :class:`~loosefit.body.avatar.Avatar`)."""
    from loosefit.eval.motion_signals import fastest_turn, turn_rate
    from loosefit.garment.mesh_checks import hem_loop

    motion = seq.motion.slice(0, frames)
    posed = avatar.pose_motion(motion)
    names = list(avatar.joint_names)
    joints = posed.joint_poses[:, :, :3, 3].cpu().numpy()  # (T, J, 3) world positions
    knees = joints[:, [names.index("LeftLeg"), names.index("RightLeg")]]
    pelvis = joints[:, 0]
    knee_frames, which = raised_knees(knees, pelvis)
    lift = np.abs(knees[knee_frames, 0, 2] - knees[knee_frames, 1, 2])
    leg = int(knee_frames[np.argmax(lift)]) if len(knee_frames) else None
    body = posed.vertices.cpu().numpy()
    body_faces = avatar.faces.cpu().numpy()
    template = seq.template
    turn = fastest_turn(motion)
    raised = dict(zip(knee_frames.tolist(), which.tolist(), strict=True))

    def covers(garment: np.ndarray, t: int) -> bool:
        return cloth_in_front(
            knees[t, raised[t]], pelvis[t], garment, template.faces, body[t], body_faces
        )

    return ClipContext(
        pelvis=pelvis,
        hem=hem_loop(template.vertices, template.faces),
        faces=np.asarray(template.faces),
        fps=float(motion.fps),
        turn=turn,
        turn_rate=float(turn_rate(motion)[turn]),
        knee_frames=knee_frames.tolist(),
        leg=leg,
        leg_height=float(lift.max()) if len(lift) else 0.0,
        covers=covers,
    )


# --------------------------------------------------------------------------- report


def knee_cover(garments: np.ndarray, ctx: ClipContext) -> np.ndarray:
    """(M, T, V, 3) -> (M, K) bool: each garment covers the raised knee at each of the clip's
    raised-knee frames (``ctx.knee_frames``)."""
    return np.array([[ctx.covers(g[t], t) for t in ctx.knee_frames] for g in garments], bool)


def score_members(members: np.ndarray, ctx: ClipContext, surface: bool = True) -> dict:
    """The members' own figures: what every model is scored against.

    Args:
        members: (M, T, V, 3) the simulations of one clip, on the same T frames.
        ctx: the clip's motion (:func:`clip_context`, on those T frames).
        surface: also Hausdorff and STED between the members (slower).

    Returns:
        The spread (RMSE per frame and over the clip, its mean and range over the pairs;
        Hausdorff and STED likewise), each member's RMSE to their mean, their own energy
        score (three members or more), their hem flare and speed over the 61 frames around
        the fastest turn, and which raised-knee frames most of them cover.
    """
    from loosefit.eval.metrics import hausdorff, sted

    members = np.asarray(members, np.float32)
    M, T = members.shape[:2]
    faces, hem, fps = ctx.faces, ctx.hem, ctx.fps
    w = turn_window(ctx.turn, T)
    pairs = pairwise_rmse(members)  # (P, T)
    pair_rmse = np.sqrt((pairs**2).mean(1))
    flare = np.stack([hem_flare(m, ctx.pelvis, hem) for m in members])  # (M, T)
    speed = np.stack([hem_speed(m, hem, fps) for m in members])
    mean = members.mean(0)
    covered = knee_cover(members, ctx)  # (M, K)
    leg = ctx.knee_frames.index(ctx.leg) if ctx.leg is not None else None
    own = {
        "members": M,
        "frames": T,
        "turn": ctx.turn,
        "turn_rate": ctx.turn_rate,
        "window": [w.start, w.stop],
        "spread_rmse_cm": 100 * float(pair_rmse.mean()),
        "spread_rmse_range_cm": [100 * float(pair_rmse.min()), 100 * float(pair_rmse.max())],
        "spread_per_frame_cm": (100 * pairs.mean(0)).tolist(),
        "member_to_mean_cm": [100 * rmse(m, mean) for m in members],
        "flare_turn_m": flare[:, w].tolist(),
        "speed_turn_m_s": speed[:, w].tolist(),
        "knee_frames": ctx.knee_frames,
        "knee_covered_by_most": (covered.sum(0) * 2 > M).tolist(),
        "leg": ctx.leg,
        "leg_height_m": ctx.leg_height,
        "leg_covered": covered[:, leg].tolist() if leg is not None else [],
    }
    if M >= 3:
        own["energy_score_cm"] = 100 * float(members_energy_score(members).mean())
    if surface:
        haus, steds = [], []
        for i in range(M):
            for j in range(i + 1, M):
                haus.append(100 * float(hausdorff(members[i], members[j], faces).mean()))
                steds.append(float(sted(members[i], members[j], faces)["sted"]))
        own.update(
            spread_hausdorff_cm=float(np.mean(haus)),
            spread_hausdorff_range_cm=[min(haus), max(haus)],
            spread_sted=float(np.mean(steds)),
            spread_sted_range=[min(steds), max(steds)],
        )
    return own


def score_model(
    samples: np.ndarray, members: np.ndarray, ctx: ClipContext, own: dict, surface: bool = True
) -> dict:
    """One model against the members.

    Args:
        samples: (S, T', V, 3) its realisations of the clip (S = 1 for a deterministic
            model; T' >= T: cut to the members' frames).
        members: (M, T, V, 3); ctx: the clip's motion; own: :func:`score_members`' figures.
        surface: also Hausdorff and STED against the members (slower).

    Returns:
        RMSE to the members' mean, RMSE against each member and its mean's ratio to the
        spread, the energy score, the share of the turn's frames whose hem flare and speed
        lie inside the members' range (and its flare over theirs), the raised-knee frames
        most members cover where it does not, and whether it covers the highest raised knee.
    """
    from loosefit.eval.metrics import hausdorff, sted

    members = np.asarray(members, np.float32)
    T = members.shape[1]
    samples = np.asarray(samples, np.float32)[:, :T]
    x = samples[0]
    w = slice(*own["window"])
    band_flare, band_speed = np.asarray(own["flare_turn_m"]), np.asarray(own["speed_turn_m_s"])
    to_members = rmse_to_members(x, members)
    fl = hem_flare(x, ctx.pelvis, ctx.hem)[w]
    sp = hem_speed(x, ctx.hem, ctx.fps)[w]
    es = energy_score(samples, members)
    cover = knee_cover(x[None], ctx)[0]
    most = own["knee_covered_by_most"]
    leg = ctx.knee_frames.index(ctx.leg) if ctx.leg is not None else None
    r = {
        "samples": int(len(samples)),
        "rmse_to_mean_cm": 100 * float(np.sqrt(np.mean(rmse_to_mean(x, members) ** 2))),
        "rmse_to_members_cm": (100 * to_members).tolist(),
        "rmse_members_ratio": float(100 * to_members.mean() / own["spread_rmse_cm"]),
        "energy_score_cm": 100 * float(es.mean()),
        "energy_per_frame_cm": (100 * es).tolist(),
        "flare_turn_m": fl.tolist(),
        "flare_in_band": float(inside_band(fl, band_flare).mean()),
        "flare_turn_ratio": float((fl / band_flare.mean(0)).mean()),
        "speed_turn_m_s": sp.tolist(),
        "speed_in_band": float(inside_band(sp, band_speed).mean()),
        "knee_missed": [
            t for t, m, c in zip(ctx.knee_frames, most, cover, strict=True) if m and not c
        ],
        "leg_covered": bool(cover[leg]) if leg is not None else None,
    }
    if surface:
        r["hausdorff_to_members_cm"] = float(
            np.mean([100 * hausdorff(x, m, ctx.faces).mean() for m in members])
        )
        r["sted_to_members"] = float(np.mean([sted(x, m, ctx.faces)["sted"] for m in members]))
    return r


def score_clip(
    preds: dict[str, np.ndarray], members: np.ndarray, ctx: ClipContext, surface: bool = True
) -> dict:
    """Every ensemble measure of one clip: the members' own (:func:`score_members`) and
    each model's against them (:func:`score_model`).

    Args:
        preds: per model, its samples (S, T', V, 3) (S = 1 for a deterministic model).
        members: (M, T, V, 3) the simulations, on the same T frames.
        ctx: the clip's motion (:func:`clip_context`, on those T frames).
        surface: also Hausdorff and STED (slower).

    Returns:
        ``{"members": ..., "models": {name: ...}}``.
    """
    own = score_members(members, ctx, surface)
    models = {n: score_model(x, members, ctx, own, surface) for n, x in preds.items()}
    return {"members": own, "models": models}


def model_samples(model, motion, realisations: int = 0, stages=None) -> np.ndarray:
    """(S, T, V, 3) float32: a model's garments of ``motion`` to score as its samples: its
    realisations 0..S-1 where ``realisations`` = S > 0 and it has a residual process
    (:mod:`loosefit.model.residual`), else its one garment (S = 1).

    Args:
        model: a trained pipeline (:func:`loosefit.load`'s ``.model``).
        motion: the motion to animate.
        realisations: S, the realisations asked for (0: the one garment).
        stages: the stages after the decoders (None: the model's).
    """
    if realisations > 0 and getattr(model, "residual", None) is not None:
        runs = [model.animate(motion, stages=stages, realisation=k) for k in range(realisations)]
    else:
        runs = [model.animate(motion, stages=stages)]
    return np.stack([np.asarray(r.vertices, np.float32) for r in runs])


def evaluate_ensemble(
    models: dict,
    sources: list[str | Path],
    split: str = "test",
    *,
    surface: bool = True,
    stages=None,
    flagged: bool = True,
    progress=None,
    ensembles: dict | None = None,
    realisations: int = 0,
) -> dict:
    """Roll models out on every clip that has members and score them against the ensemble.

    Args:
        models: name -> a trained pipeline (:func:`loosefit.load`'s ``.model``;
            ours, a baseline), each rolled out once on each clip's first member's motion.
        sources: data set folders of the same clips (the corpus first).
        split: the first data set's clips to score.
        surface: also Hausdorff and STED.
        stages: the stages after the decoders (default: each model's, all of them).
        flagged: count members the simulator's quality gate flagged.
        progress: ``progress(message)`` or None.
        ensembles: the members already gathered (:func:`gather_ensembles` of ``sources``).
        realisations: S > 0: a model with a residual process (its seeded realisations,
            :mod:`loosefit.model.residual`) is scored by its realisations 0..S-1 as its
            samples; 0 (and any other model): its one garment.

    Returns:
        ``{"split", "sources", "clips"}``: per clip, :func:`score_clip`'s figures and the
        members' labels, sources and flags.

    Raises:
        LoosefitInputError: no clip with two members (with how to make more), or members
            that differ in anything but the seed.
    """
    from loosefit.inference.model_common import avatar_of

    if ensembles is None:
        ensembles = gather_ensembles(sources, split, flagged)
    many = {k: e for k, e in ensembles.items() if len(e.members) >= 2}
    if not many:
        raise LoosefitInputError(
            ", ".join(str(s) for s in sources),
            "members",
            "at least one clip simulated from two or more seeds",
            "one member of every clip",
            hint="simulate the clips again from other seeds (loosefit simulate --seeds "
            "0,1,2,3, or --config with another seed) and pass those data sets too",
        )
    out = {}
    for clip, ens in many.items():
        first = ens.sequences[0]
        members = ens.vertices()
        avatar = avatar_of(ens.members[0].reader.body)
        ctx = clip_context(first, ens.frames, avatar)
        motion = first.motion.slice(0, ens.frames)
        preds = {}
        for name, model in models.items():
            if progress:
                progress(f"{clip}: {name} on {ens.frames} frames")
            preds[name] = model_samples(model, motion, realisations, stages)
        scored = score_clip(preds, members, ctx, surface=surface)
        scored["members"]["labels"] = [m.label for m in ens.members]
        scored["members"]["sources"] = [f"{m.source}:{m.name}" for m in ens.members]
        scored["members"]["flagged"] = [m.flagged for m in ens.members]
        scored["members"]["motion_difference"] = ens.motion_difference
        out[clip] = scored
    return {"split": split, "sources": [str(s) for s in sources], "clips": out}


def ensemble_markdown(result: dict) -> str:
    """The ensemble measures as Markdown tables: per clip, the members' spread and each
    model's scores against them."""
    lines = [
        "## Against an ensemble of simulations",
        "",
        "Each clip's members: the same motion simulated from different seeds. Spread: "
        "each member against each other (the chaos floor, mean and range over the "
        "pairs). Per model: RMSE to the members' vertex-wise mean; the mean of its RMSE "
        "against each member and its ratio to the spread; the energy score (lower is "
        "better; a mean is not rewarded); the share of the 61 frames around the fastest "
        "turn whose hem flare and hem speed lie within the members' range; the "
        "raised-knee frames most members cover where the model does not.",
        "",
    ]
    for clip, c in result["clips"].items():
        m = c["members"]
        flagged = [lab for lab, f in zip(m["labels"], m["flagged"], strict=True) if f]
        lines += [
            f"### `{clip}` ({m['frames']} frames, {m['members']} members: "
            f"{', '.join(m['labels'])}{'; flagged by the simulator: ' + ', '.join(flagged) if flagged else ''})",  # noqa: E501
            "",
            f"Fastest turn at frame {m['turn']} ({m['turn_rate']:.1f} rad/s); "
            + (
                f"the highest raised knee at frame {m['leg']} ({100 * m['leg_height_m']:.0f} "
                f"cm above the other), covered by {sum(m['leg_covered'])} of "
                f"{m['members']} members; {sum(m['knee_covered_by_most'])} of "
                f"{len(m['knee_frames'])} raised-knee frames covered by most members."
                if m["leg"] is not None
                else "no knee raised under the pelvis."
            ),
            "",
        ]
        has_surface = "spread_hausdorff_cm" in m
        head = "| | RMSE to members cm (x spread) | RMSE to mean cm | energy score cm |"
        rule = "|---|---:|---:|---:|"
        if has_surface:
            head += " Hausdorff cm | STED |"
            rule += "---:|---:|"
        head += " flare in band % | speed in band % | flare / members' mean | knee missed |"
        rule += "---:|---:|---:|---:|"
        lo, hi = m["spread_rmse_range_cm"]
        row = (
            f"| members (spread) | {m['spread_rmse_cm']:.2f} ({lo:.2f}-{hi:.2f}) | "
            f"{np.mean(m['member_to_mean_cm']):.2f} | "
            f"{m['energy_score_cm']:.2f} |"
            if "energy_score_cm" in m
            else f"| members (spread) | {m['spread_rmse_cm']:.2f} ({lo:.2f}-{hi:.2f}) | "
            f"{np.mean(m['member_to_mean_cm']):.2f} | - |"
        )
        if has_surface:
            row += f" {m['spread_hausdorff_cm']:.2f} | {m['spread_sted']:.4f} |"
        row += " 100 | 100 | 1.00 | - |"
        lines += [head, rule, row]
        for name, r in c["models"].items():
            to = float(np.mean(r["rmse_to_members_cm"]))
            row = (
                f"| {name} | {to:.2f} ({r['rmse_members_ratio']:.2f}x) | "
                f"{r['rmse_to_mean_cm']:.2f} | {r['energy_score_cm']:.2f} |"
            )
            if has_surface:
                row += f" {r['hausdorff_to_members_cm']:.2f} | {r['sted_to_members']:.4f} |"
            row += (
                f" {100 * r['flare_in_band']:.0f} | {100 * r['speed_in_band']:.0f} | "
                f"{r['flare_turn_ratio']:.2f} | {len(r['knee_missed'])} |"
            )
            lines.append(row)
        lines.append("")
    return "\n".join(lines)
