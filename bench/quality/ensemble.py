"""docs/results/ENSEMBLE.md: every method against an ensemble of simulations of each held-out clip.

Cloth is chaotic, so one simulation of a clip is one sample of what the cloth may do. The
held-out clips simulated again from other seeds (``../shared/datasets/dance-seeds``, or
``loosefit simulate --seeds``) give each clip several members; this scores every method
against all of them (:mod:`loosefit.eval.ensemble`): the members' own spread (the chaos
floor), RMSE to their mean, RMSE against each member over the spread's, the energy score,
hem flare and speed around the fastest turn against the members' range, the raised knee;
the generative model's own reconstruction of each clip against the floor; the targets;
a plot of the hem's flare against the members' band; renders at each clip's fastest turn
and highest raised knee (the members | ours)::

    python bench/quality/ensemble.py --data datasets/dance \\
        --members datasets/dance-seeds/seed1 datasets/dance-seeds/seed2 \\
        datasets/dance-seeds/seed3 --checkpoint checkpoints/dance/motion.pt \\
        --baselines runs/dance/baselines --results docs/results/RESULTS.md

Rollouts and scores are cached in ``--cache`` (a killed run goes on from what it has).
``--results`` puts the tables into docs/results/RESULTS.md as its ensemble section
(replacing the one there); ``bench/quality/results.py --ensemble docs/results/ENSEMBLE.md``
includes it when it writes the whole file.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch

import loosefit
from loosefit.eval.ensemble import (
    SECTION,
    clip_context,
    ensemble_markdown,
    model_samples,
    score_members,
    score_model,
)
from loosefit.eval.ensemble_members import gather_ensembles
from loosefit.inference.model_common import avatar_of
from loosefit.inference.stages import MOTION_ONLY, Stages
from loosefit.train.common import machine

# the figures of a page docs/X.md as JSON: bench/figures/X.json
FIGURES = Path(__file__).resolve().parents[1] / "figures"


RAW = Stages(detail=False, lengths=False, collision=False)
# key: (label, checkpoint kind, stages)
METHODS = {
    "ours-full": ("ours, the shipped set (every stage; deterministic)", "ours", Stages()),
    "ours-realisations": ("ours, the shipped set's realisations (every stage; its residual "
                          "process)", "ours", Stages()),
    "ours-motion": ("ours w/o detail and collision (motion stage)", "ours", MOTION_ONLY),
    "santesteban-push": ("Santesteban et al. 2019 style + their push-out", "santesteban",
                         Stages(detail=False, lengths=False)),
    "virtual-bones": ("Pan et al. 2022 style (virtual bones + residual)", "virtual-bones", RAW),
}  # fmt: skip
FLARE_SHARE = 0.80  # of the turn's frames inside the members' range
RMSE_RATIO = 1.25  # RMSE against the members over their own
DECODER_SHARE = 0.5  # the decoder's reconstruction over the chaos floor
RMSE_MEAN_BOUND = 1.05  # a stochastic stage's RMSE to the members' mean over the deterministic's
STED_BOUND = 1.10  # its STED over the deterministic set's


def rollouts(args, ens, motion, cache: Path) -> dict:
    """Each method's garment on a clip's shared frames (cached), and the decoder's
    reconstruction of the first member (the oracle)."""
    cache.mkdir(parents=True, exist_ok=True)
    models, out = {}, {}
    engines = [(engine_key(e), ("", "engine", e)) for e in args.engines]
    for key, (_, kind, stages) in [*METHODS.items(), ("oracle", ("", "ours", None)), *engines]:
        path = cache / f"{key}.npz"
        ckpt = {"ours": args.checkpoint, "engine": stages}.get(
            kind, Path(args.baselines, kind, "model.pt")
        )
        if not Path(ckpt).is_file():
            continue  # a baseline not trained
        if not path.is_file():
            if kind == "engine":
                from loosefit.inference.engine.model import load_engine, rollout_engine

                models[key] = load_engine(ckpt)
            elif kind not in models:
                models[kind] = loosefit.load(ckpt).model
            t0 = time.perf_counter()
            if kind == "engine":  # a stochastic tier: args.samples realisations (seeds)
                seeds = range(args.samples if models[key].tier.config.noise else 1)
                result = Rollout(
                    np.stack([rollout_engine(models[key], motion, seed=k) for k in seeds])
                )
            elif key == "oracle":
                truth = ens.members[0].read().garment_vertices[: ens.frames]
                result = models[kind].reconstruct(motion, truth)
            elif key == "ours-realisations":  # seeds 0, 1, ... of its residual process
                if models[kind].residual is None:
                    continue  # a set without one
                result = Rollout(model_samples(models[kind], motion, args.samples, stages))
            else:
                result = models[kind].animate(motion, stages=stages)
            seconds = time.perf_counter() - t0
            tmp = path.with_name(path.stem + ".partial.npz")
            np.savez(tmp, vertices=result.vertices.astype(np.float32), seconds=seconds)
            tmp.replace(path)
            print(f"{ens.clip} {key}: {ens.frames} frames in {seconds:.1f} s", flush=True)
        with np.load(path) as z:
            out[key] = z["vertices"]
    return out


class Rollout:
    """An engine tier's garments where a pipeline's result is read (``.vertices``)."""

    def __init__(self, vertices: np.ndarray) -> None:
        self.vertices = vertices


def engine_key(path: str) -> str:
    """A method key for an engine tier's checkpoint: its run folder's name."""
    return f"engine:{Path(path).parent.name}"


def label_of(key: str) -> str:
    if key in METHODS:
        return METHODS[key][0]
    if key == "engine:dance":
        return "the shipped set's engine tier (64 directions, distilled; no push-out)"
    if key.startswith("engine:"):
        name = key.removeprefix("engine:")
        what = {
            "engine-k128": "128 directions, squared error",
            "engine-k128-es": "128 directions, stochastic, energy score",
            "engine-k128-es-ar": "128 directions, stochastic with noise correlated in time "
            "(rho 0.95), energy score",
        }.get(name, name)
        return f"a linear basis and its recurrent step ({what})"
    return "oracle: the generative model's reconstruction of the first member"


def clip_scores(ens, seqs, garments: dict, ctx, cache: Path) -> dict:
    """The members' figures and each method's against them, each cached in its own file
    (a method added later is scored alone)."""
    members = np.stack([s.garment_vertices[: ens.frames] for s in seqs])
    path = cache / "members.json"
    if not path.is_file():
        own = score_members(members, ctx)
        own["labels"] = [m.label for m in ens.members]
        own["flagged"] = [m.flagged for m in ens.members]
        own["sources"] = [f"{m.source}:{m.name}" for m in ens.members]
        path.write_text(json.dumps(own))
    own = json.loads(path.read_text())
    models = {}
    for key, vertices in garments.items():
        path = cache / f"{key}.json"
        if not path.is_file():
            samples = vertices if vertices.ndim == 4 else vertices[None]  # (S, T, V, 3)
            path.write_text(json.dumps(score_model(samples, members, ctx, own)))
            print(f"{ens.clip} {key}: scored", flush=True)
        models[key] = json.loads(path.read_text())
    return {"members": own, "models": models}


def validation_choice(args, cache: Path) -> dict:
    """Each candidate set's energy score on the validation clips (simulated, never trained
    on, not held out), one simulation each: the score that chooses the shipped set.

    Returns:
        Per candidate (ours, each engine tier): its mean energy score (cm) over the clips'
        frames and per clip.
    """
    from loosefit.data.format import DatasetReader
    from loosefit.eval.ensemble import energy_score
    from loosefit.eval.heldout import validation_clips

    reader = DatasetReader(args.data)
    out: dict[str, dict] = {}
    models: dict = {}
    for clip in validation_clips(reader):
        seq = reader.read(clip)
        truth = seq.garment_vertices[None]
        for key in ["ours-full", "ours-realisations", *(engine_key(e) for e in args.engines)]:
            path = cache / "validation" / clip / f"{key}.npz"
            path.parent.mkdir(parents=True, exist_ok=True)
            if not path.is_file():
                if key.startswith("ours-"):
                    if "ours" not in models:
                        models["ours"] = loosefit.load(args.checkpoint).model
                    ours = models["ours"]
                    if key == "ours-full":
                        x = ours.animate(seq.motion).vertices[None]
                    elif ours.residual is None:
                        continue  # a set without a residual process
                    else:
                        x = model_samples(ours, seq.motion, args.samples)
                else:
                    from loosefit.inference.engine.model import load_engine, rollout_engine

                    where = next(e for e in args.engines if engine_key(e) == key)
                    if key not in models:
                        models[key] = load_engine(where)
                    S = args.samples if models[key].tier.config.noise else 1
                    x = np.stack(
                        [rollout_engine(models[key], seq.motion, seed=k) for k in range(S)]
                    )
                tmp = path.with_name(path.stem + ".partial.npz")
                np.savez(tmp, vertices=x.astype(np.float32))
                tmp.replace(path)
                print(f"validation {clip} {key}: rolled out", flush=True)
            with np.load(path) as z:
                es = energy_score(z["vertices"], truth)
            entry = out.setdefault(key, {"clips": {}, "frames": 0, "sum": 0.0})
            entry["clips"][clip] = 100 * float(es.mean())
            entry["frames"] += len(es)
            entry["sum"] += 100 * float(es.sum())
    for entry in out.values():
        entry["energy_score_cm"] = entry.pop("sum") / max(entry["frames"], 1)
    return out


def validation_section(choice: dict) -> list[str]:
    if not choice:
        return []
    best = min(choice, key=lambda k: choice[k]["energy_score_cm"])
    clips = list(next(iter(choice.values()))["clips"])
    lines = [
        "### The validation clips' choice",
        "",
        "Each candidate against the one simulation of each validation clip (simulated, "
        "never trained on, not held out: the clips `bench/quality/compare_sets.py` chooses "
        "with), by the energy score (cm; lower is better; a stochastic candidate with "
        "its realisations): what chooses the shipped set. The held-out clips above "
        "never decide.",
        "",
        "| candidate | mean | " + " | ".join(f"`{c}`" for c in clips) + " |",
        "|---|---:|" + "---:|" * len(clips),
    ]
    for key, entry in choice.items():
        lines.append(
            f"| {label_of(key)} | {entry['energy_score_cm']:.2f} | "
            + " | ".join(f"{entry['clips'][c]:.2f}" for c in clips)
            + " |"
        )
    lines += ["", f"Chosen: {label_of(best)}.", ""]
    return lines


def flare_plot(path: Path, scores: dict) -> None:
    """Per clip: the members' hem flare around the fastest turn (their band and each
    member), ours and the baselines over it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    clips = list(scores)
    fig, axes = plt.subplots(2, len(clips), figsize=(4.2 * len(clips), 6.4), squeeze=False)
    for col, clip in enumerate(clips):
        c = scores[clip]
        m = c["members"]
        t = np.arange(*m["window"])
        series = (("flare_turn_m", "hem flare (cm)", 100), ("speed_turn_m_s", "hem speed (m/s)", 1))
        for row, (key, unit, scale) in enumerate(series):
            ax = axes[row, col]
            band = scale * np.asarray(m[key])
            ax.fill_between(t, band.min(0), band.max(0), color="0.85", label="members' range")
            for k, b in enumerate(band):
                ax.plot(t, b, color="0.55", lw=0.8, label="members" if k == 0 else None)
            for name, r in c["models"].items():
                if name == "oracle":
                    continue
                ax.plot(t, scale * np.asarray(r[key]), lw=1.4, label=label_of(name)[:40])
            ax.axvline(m["turn"], color="k", ls=":", lw=0.8)
            ax.set_xlabel("frame")
            ax.set_ylabel(unit)
            if row == 0:
                ax.set_title(
                    f"{clip} (turn at {m['turn']}, {m['turn_rate']:.1f} rad/s)", fontsize=9
                )
    axes[0, 0].legend(fontsize=6, loc="best")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def clip_renders(args, ens, seqs, ctx, garments: dict, img: Path, missed: list[int]) -> dict:
    """The members and ours at the clip's fastest turn and at a raised knee (the middle one of
    the frames where most members cover it and ours does not, ``missed``, else the highest),
    coloured by the distance to the first member."""
    from loosefit.eval.renders import error_sheet

    avatar = avatar_of(ens.members[0].reader.body)
    motion = seqs[0].motion.slice(0, ens.frames)
    body = avatar.pose_motion(motion).vertices.cpu().numpy()
    body_faces = avatar.faces.cpu().numpy()
    truth = seqs[0].garment_vertices[: ens.frames]
    shown = {}
    knee = missed[len(missed) // 2] if missed else ctx.leg
    frames = {"turn": ctx.turn, **({"leg": knee} if knee is not None else {})}
    for what, frame in frames.items():
        path = img / f"ensemble_{ens.clip}_{what}.jpg"
        picks = {
            f"member, {m.label}": s.garment_vertices[frame]
            for m, s in zip(ens.members[1:], seqs[1:], strict=True)
        }
        picks["ours"] = garments["ours-full"][frame]
        error_sheet(
            path,
            frame,
            truth,
            picks,
            body,
            body_faces,
            faces=seqs[0].template.faces,
            vmax=15.0,
            size=args.size,
            where=ens.clip,
            truth_label=f"member, {ens.members[0].label}",
        )
        shown[what] = {"frame": frame, "path": str(path)}
    return shown


def targets(scores: dict) -> list[str]:
    """The targets, clip by clip, ours (the shipped set) against the members."""
    lines = [
        "### The targets, read off the tables",
        "",
        "| clip | decoder / floor (<= 0.5) | flare in band (>= 80 %) | RMSE to members / "
        "spread (<= 1.25) | knee frames missed (0) |",
        "|---|---:|---:|---:|---:|",
    ]
    misses = []
    for clip, c in scores.items():
        m, r = c["members"], c["models"]["ours-full"]
        decoder = c["models"]["oracle"]["rmse_to_members_cm"][0] / m["spread_rmse_cm"]
        row = [
            decoder <= DECODER_SHARE,
            r["flare_in_band"] >= FLARE_SHARE,
            r["rmse_members_ratio"] <= RMSE_RATIO,
            not r["knee_missed"],
        ]
        names = ["decoder", "flare", "RMSE", "knee"]
        misses += [f"{clip}: {n}" for n, ok in zip(names, row, strict=True) if not ok]
        lines.append(
            f"| {clip} | {decoder:.2f} | {100 * r['flare_in_band']:.0f} % | "
            f"{r['rmse_members_ratio']:.2f} | {len(r['knee_missed'])} |"
        )
    lines += ["", f"**Missed:** {', '.join(misses)}." if misses else "All met.", ""]
    stochastic = sorted(
        {k for c in scores.values() for k, r in c["models"].items() if r["samples"] > 1}
    )
    if not stochastic:
        lines += [
            "The energy score of a stochastic motion stage below the deterministic "
            "set's: no stochastic candidate was scored (the shipped set is "
            "deterministic: one sample).",
            "",
        ]
    for key in stochastic:
        cells = []
        for clip, c in scores.items():
            mine, det = c["models"][key], c["models"]["ours-full"]
            cells.append(
                f"{clip} {mine['energy_score_cm']:.2f} against {det['energy_score_cm']:.2f}"
            )
        below = all(
            c["models"][key]["energy_score_cm"] < c["models"]["ours-full"]["energy_score_cm"]
            for c in scores.values()
        )
        lines += [
            f"{label_of(key)} ({mine['samples']} realisations, seeds 0-"
            f"{mine['samples'] - 1}): energy score below the deterministic set's on "
            f"every clip: **{'met' if below else 'not met'}** ({'; '.join(cells)} cm).",
            "",
        ]
        for what, field, bound in (
            ("RMSE to the members' mean", "rmse_to_mean_cm", RMSE_MEAN_BOUND),
            ("STED", "sted_to_members", STED_BOUND),
        ):
            ratios = {
                clip: c["models"][key][field] / c["models"]["ours-full"][field]
                for clip, c in scores.items()
                if field in c["models"][key]
            }
            if not ratios:
                continue
            ok = all(r <= bound for r in ratios.values())
            said = "; ".join(f"{clip} {r:.3f}" for clip, r in ratios.items())
            lines += [
                f"Its {what} (its first realisation's) at most {bound:g}x the deterministic "
                f"set's on every clip: **{'met' if ok else 'not met'}** ({said}).",
                "",
            ]
    return lines


def markdown(
    args, scores: dict, renders_shown: dict, started: str, choice: dict | None = None
) -> str:
    labelled = {"split": "test", "sources": [], "clips": {}}
    for clip, c in scores.items():
        models = {label_of(k): v for k, v in c["models"].items()}
        labelled["clips"][clip] = {"members": c["members"], "models": models}
    table = ensemble_markdown(labelled).splitlines()
    body = [("#" + line if line.startswith("### ") else line) for line in table[1:]]
    lines = [
        SECTION,
        "",
        f"Made by `python bench/quality/ensemble.py` (its docstring gives the command) on "
        f"`{args.data}` with members from {', '.join(f'`{m}`' for m in args.members)}; "
        f"this run started {started} on {machine('cpu')}. The oracle row is the floor under "
        "every motion stage on this decoder: the generative model's own code of the "
        "first member's garment, decoded, scored like the methods.",
        "",
        "![hem flare and speed around each clip's fastest turn against the members' "
        "range](../img/ensemble_flare.png)",
        "",
        *targets(scores),
        *validation_section(choice or {}),
        *body,
    ]
    for clip, shown in renders_shown.items():
        for what, s in shown.items():
            missed = scores[clip]["models"]["ours-full"]["knee_missed"]
            title = (
                "its fastest turn"
                if what == "turn"
                else "a raised knee most members cover and ours does not"
                if missed
                else "its highest raised knee"
            )
            lines += [
                f"`{clip}` at {title} (frame {s['frame']}): the first member | the "
                "others | ours, coloured by the distance to the first member.",
                "",
                f"![{clip} at {title}](../img/{Path(s['path']).name})",
                "",
            ]
    return "\n".join(lines).rstrip() + "\n"


def splice(results: Path, section: str) -> None:
    """Put ``section`` into docs/results/RESULTS.md in place of its ensemble section (before the
    first section after the targets where it has none)."""
    from loosefit.eval.report import splice_section

    results.write_text(splice_section(results.read_text(), SECTION, section))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--data", default="datasets/dance")
    p.add_argument("--members", nargs="+", required=True, help="data sets of other seeds")
    p.add_argument("--checkpoint", default="checkpoints/dance/motion.pt", help="ours")
    p.add_argument("--baselines", default="runs/dance/baselines")
    p.add_argument(
        "--engines", nargs="*", default=[], help="engine tiers (engine.pt) scored as methods too"
    )
    p.add_argument(
        "--validation",
        action="store_true",
        help="also choose among ours and the engine tiers by the energy score on "
        "the validation clips",
    )
    p.add_argument(
        "--samples",
        type=int,
        default=8,
        help="realisations (seeds 0, 1, ...) of a stochastic method",
    )
    p.add_argument("--cache", default="runs/dance/ensemble")
    p.add_argument("--out", default="docs/results/ENSEMBLE.md")
    p.add_argument("--img", default="docs/img")
    p.add_argument("--results", default=None, help="docs/results/RESULTS.md: its ensemble section")
    p.add_argument("--size", type=int, default=300, help="pixels per view of the renders")
    p.add_argument("--threads", type=int, default=1)
    args = p.parse_args()
    torch.set_num_threads(args.threads)
    started = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    cache, img = Path(args.cache), Path(args.img)
    img.mkdir(parents=True, exist_ok=True)
    ensembles = gather_ensembles([args.data, *args.members])
    scores, shown = {}, {}
    for clip, ens in ensembles.items():
        if len(ens.members) < 2:
            print(f"{clip}: one member, left out")
            continue
        seqs = ens.sequences
        motion = seqs[0].motion.slice(0, ens.frames)
        garments = rollouts(args, ens, motion, cache / clip)
        avatar = avatar_of(ens.members[0].reader.body)
        ctx = clip_context(seqs[0], ens.frames, avatar)
        scores[clip] = clip_scores(ens, seqs, garments, ctx, cache / clip)
        missed = scores[clip]["models"]["ours-full"]["knee_missed"]
        shown[clip] = clip_renders(args, ens, seqs, ctx, garments, img, missed)
        print(f"{clip}: scored", flush=True)
    flare_plot(img / "ensemble_flare.png", scores)
    choice = validation_choice(args, cache) if args.validation else {}
    text = markdown(args, scores, shown, started, choice)
    Path(args.out).write_text(
        "# Dynamics against an ensemble of simulations\n\n" + text.replace(SECTION + "\n\n", "", 1)
    )

    def brief(d: dict) -> dict:  # the per-frame series left out
        return {a: b for a, b in d.items() if "per_frame" not in a}

    light = {
        k: {"members": brief(v["members"]), "models": {n: brief(r) for n, r in v["models"].items()}}
        for k, v in scores.items()
    }
    (FIGURES / f"{Path(args.out).stem}.json").write_text(
        json.dumps(
            {"started": started, "machine": machine("cpu"), "clips": light, "validation": choice},
            indent=1,
        )
    )
    if args.results:
        splice(Path(args.results), text)
    print(f"wrote {args.out}" + (f" and the section of {args.results}" if args.results else ""))


if __name__ == "__main__":
    main()
