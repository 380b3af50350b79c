"""docs/results/RESULTS.md: every method against the simulation on the held-out clips
(paper 4.2-4.3).

Table 3's form on each held-out set of the data set: the salsa chain (60_03 + 60_07 +
61_03 + 61_07, 1,957 frames) and, on ``dance``, the three held-out ballet clips (05_02,
05_10, 05_12), each clip rolled out whole from its first frame on the same motion by every
method, never seen in training: RMSE, Hausdorff, STED, vertices inside the body and edge
strain (a set's clips pooled frame by frame), and frames per second; the ratios of ours to
each baseline; the generative-model ablation (Fig. 4, two seeds each: the run-to-run
noise); a plot of every method's RMSE per frame over each clip; the fastest turn of each
set rendered side by side (simulation | ours | virtual bones | Santesteban), coloured by
per-vertex error::

    python bench/quality/results.py --data datasets/salsa --baselines runs/salsa/baselines \\
        --ablation runs/salsa/ablation --out docs/results/RESULTS.md

Rollouts and their scores are cached in ``--cache`` (a killed run goes on from the
methods it has); ``scripts/results.sh`` trains what this reads, then runs it.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch

import loosefit
from loosefit.data.format import DatasetReader
from loosefit.eval.metrics import hausdorff, inside_fraction, rmse_per_frame, sted
from loosefit.eval.motion_signals import fastest_turn, highest_leg, turn_rate
from loosefit.eval.renders import error_sheet
from loosefit.garment.quality import edge_strain
from loosefit.inference.stages import MOTION_ONLY, Stages
from loosefit.sim.presets import BALLET_CLIPS
from loosefit.train.common import machine

RAW = Stages(detail=False, lengths=False, collision=False)
# key: (label, checkpoint kind, stages)
METHODS = {
    "santesteban": ("Santesteban et al. 2019 style, no post-process", "santesteban", RAW),
    "santesteban-push": ("Santesteban et al. 2019 style + their push-out", "santesteban",
                         Stages(detail=False, lengths=False)),
    "virtual-bones": ("Pan et al. 2022 style (virtual bones + residual)", "virtual-bones", RAW),
    "ours-motion": ("ours w/o detail and collision (motion stage)", "ours", MOTION_ONLY),
    "ours-full": ("ours, the shipped pipeline (every stage of the set)", "ours", Stages()),
    # the same motion stage with the detail stage trained for it (--with-detail: a set
    # that has one), where the shipped set has none
    "ours-detail": ("ours + the detail stage (trained, not shipped)", "ours-detail", Stages()),
}  # fmt: skip
SEEDED = ("santesteban", "santesteban-push", "virtual-bones")  # trained with a second seed too
for _key in SEEDED:  # the second seed's run (METHOD-s1), where it was trained
    _label, _kind, _stages = METHODS[_key]
    METHODS[f"{_key}-s1"] = (f"{_label}, seed 1", f"{_kind}-s1", _stages)
PAPER_RATIOS = {"santesteban": 0.62, "virtual-bones": 0.75}  # ours / baseline RMSE, Table 3


def rollouts(args, reader: DatasetReader, name: str, cache: Path) -> dict:
    """Each method's garment over one held-out clip (cached), and the seconds it took."""
    seq = reader.read(name)
    cache.mkdir(parents=True, exist_ok=True)
    models = {}
    out = {}
    for key, (_, kind, stages) in METHODS.items():
        path = cache / f"{key}.npz"
        ckpt = {"ours": args.checkpoint, "ours-detail": args.with_detail}.get(
            kind, Path(args.baselines, kind, "model.pt")
        )
        if ckpt is None or not Path(ckpt).is_file():
            continue  # a baseline (or its second seed) not trained, or no --with-detail
        if not path.is_file():
            if kind not in models:
                models[kind] = loosefit.load(ckpt).model
            t0 = time.perf_counter()
            result = models[kind].animate(seq.motion, stages=stages)
            seconds = time.perf_counter() - t0
            tmp = path.with_name(path.stem + ".partial.npz")
            np.savez(
                tmp,
                vertices=result.vertices.astype(np.float32),
                seconds=seconds,
                frames=result.frames,
            )
            tmp.replace(path)
            print(f"{key}: rolled out in {seconds:.1f} s")
        with np.load(path) as z:
            out[key] = {
                "vertices": z["vertices"],
                "seconds": float(z["seconds"]),
                "frames": int(z["frames"]),
            }
    return out


def score(parts: list[dict], template) -> dict:
    """One method on a held-out set: its clips' frames pooled.

    Args:
        parts: per clip ``{"vertices", "truth", "body", "collider", "fps"}``, (T, V, 3)
            garments, (T, Vb, 3) body, (F, 3) collider faces.

    Returns:
        RMSE and Hausdorff (cm) over every frame of the set, STED (the clips' mean weighted
        by their frames), inside the body (% of vertices, mean and p99 over frames), edge
        strain (p50, p99 over edges and frames), and the RMSE of every frame per clip.
    """
    per, haus, inside, strain, steds, frames = [], [], [], [], [], []
    for c in parts:
        v, g, faces = c["vertices"], c["truth"], template.faces
        per.append(100 * rmse_per_frame(v, g))
        haus.append(100 * hausdorff(v, g, faces))
        inside.append(100 * inside_fraction(v, c["body"], c["collider"]))
        strain.append(edge_strain(v, template)[0].reshape(-1))
        steds.append(float(sted(v, g, faces)["sted"]))
        frames.append(len(v))
    all_per, all_inside = np.concatenate(per), np.concatenate(inside)
    all_strain = np.concatenate(strain)
    return {
        "rmse_cm": float(np.sqrt(np.mean(all_per**2))),
        "hausdorff_cm": float(np.concatenate(haus).mean()),
        "sted": float(np.average(steds, weights=frames)),
        "inside_mean_pct": float(all_inside.mean()),
        "inside_p99_pct": float(np.percentile(all_inside, 99)),
        "strain_p50": float(np.median(all_strain)),
        "strain_p99": float(np.percentile(all_strain, 99)),
        "rmse_per_frame_cm": [p.tolist() for p in per],
        "rmse_per_clip_cm": [float(np.sqrt(np.mean(p**2))) for p in per],
        "sted_per_clip": steds,
    }


def heldout_sets(reader: DatasetReader) -> dict[str, list[str]]:
    """The held-out clips as the tables group them: the salsa chain, the ballet clips
    (``dance``), any other held-out clip; each clip rolled out whole."""
    sets: dict[str, list[str]] = {}
    for name in reader.split("test"):
        key = (
            "chain" if name.startswith("chain_") else "ballet" if name in BALLET_CLIPS else "other"
        )
        sets.setdefault(key, []).append(name)
    return sets


SET_TITLES = {
    "chain": "the held-out salsa chain",
    "ballet": "the held-out ballet clips",
    "other": "the other held-out clips",
}


def plot_per_frame(
    path: Path, scores: dict, clips: list[str], spins: list[int], title: str
) -> None:
    """Every method's RMSE per frame, one panel per clip of the set."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(
        len(clips), 1, figsize=(10, 1 + 3 * len(clips)), dpi=110, squeeze=False
    )
    for i, (ax, clip, spin) in enumerate(zip(axes[:, 0], clips, spins, strict=True)):
        for key, s in scores.items():
            ax.plot(s["rmse_per_frame_cm"][i], lw=0.9, label=METHODS[key][0])
        ax.axvline(spin, color="0.5", lw=0.8, ls="--")
        ax.set_ylim(bottom=0)
        ax.text(spin, ax.get_ylim()[1] * 0.92, " fastest turn", fontsize=8, color="0.4")
        ax.set_xlabel(f"frame of {clip}")
        ax.set_ylabel("RMSE (cm)")
    axes[0, 0].set_title(title)
    axes[0, 0].legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def ablation_section(ablation: Path) -> list[str]:
    """The generative ablation's table (bench/ablations/generative_ablation.py's), from its runs."""
    from loosefit.eval.generative_report import DECODERS, format_table

    rows: dict[str, list[dict]] = {}
    for decoder in DECODERS:
        for run in sorted(ablation.glob(f"{decoder}*/report.json")):
            if run.parent.name != decoder and not run.parent.name.startswith(f"{decoder}-s"):
                continue
            seed = 0 if run.parent.name == decoder else int(run.parent.name.split("-s")[-1])
            rows.setdefault(decoder, []).append({"seed": seed, **json.loads(run.read_text())})
    if not rows:
        return ["(no ablation runs in " + str(ablation) + ")"]
    return format_table(rows, Path(ablation).parent.name, "cpu").splitlines()


def ablation_figures(
    ablation: Path, cache: Path, reader, seq, body, body_faces, spin: int, img: Path, size: int
) -> dict:
    """Each decoder's (seed 0) reconstruction of the chain: per-frame RMSE and a render.

    Returns:
        Per decoder: the RMSE of every frame (cm).
    """
    from loosefit.eval.generative_report import DECODERS
    from loosefit.inference.checkpoints import load_generative
    from loosefit.inference.references import reconstruction

    truth = seq.garment_vertices
    recon = {}
    for decoder in DECODERS:
        ckpt, path = ablation / decoder / "checkpoint.pt", cache / f"recon-{decoder}.npy"
        if not ckpt.is_file():
            continue
        if not path.is_file():
            model, _ = load_generative(ckpt)
            with torch.no_grad():
                r = reconstruction(model, seq.motion, truth, float(reader.body["floor_height"]))
            np.save(path, r.vertices.astype(np.float32))
        recon[decoder] = np.load(path)
    if not recon:
        return {}
    per = {d: 100 * rmse_per_frame(v, truth) for d, v in recon.items()}
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(10, 3.6), dpi=110)
    for d, e in per.items():
        ax.plot(e, lw=0.9, label=f"{DECODERS[d]} ({np.sqrt(np.mean(e**2)):.2f} cm)")
    ax.axvline(spin, color="0.5", lw=0.8, ls="--")
    ax.set_xlabel("frame of the held-out chain")
    ax.set_ylabel("reconstruction RMSE (cm)")
    ax.set_ylim(bottom=0)
    ax.set_title("the generative model's ablation: each decoder's reconstruction of the chain")
    ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    fig.savefig(img / "results_ablation_per_frame.png")
    plt.close(fig)
    labels = {
        "decomposed": "decomposed (ours)",
        "vertex": "single vertex decoder",
        "ssdr": "SSDR linear decoder",
    }
    picks = {labels[d]: v[spin] for d, v in recon.items()}
    error_sheet(
        img / "results_ablation_spin.jpg",
        spin,
        truth,
        picks,
        body,
        body_faces,
        faces=reader.template.faces,
        vmax=8.0,
        size=size,
    )
    return {d: e.tolist() for d, e in per.items()}


def clip_data(args, reader: DatasetReader, name: str, cache: Path, ours) -> dict:
    """One held-out clip: every method's rollout (cached), the simulation, the body."""
    garments = rollouts(args, reader, name, cache / name)
    seq = reader.read(name)
    avatar = ours.avatar()
    body = avatar.pose_motion(seq.motion).vertices.cpu().numpy()
    collider = avatar.collider_faces(arms=ours.arm_collision).cpu().numpy()
    feet = [avatar.joint_names.index(j) for j in ("LeftFoot", "RightFoot")]
    feet_z = avatar.pose_motion(seq.motion).joint_poses[:, feet, 2, 3].cpu().numpy()
    return {
        "name": name,
        "seq": seq,
        "garments": garments,
        "body": body,
        "collider": collider,
        "body_faces": avatar.faces.cpu().numpy(),
        "feet_z": feet_z,
    }


def simulation_scores(clips: list[dict], template) -> dict:
    """The simulation's own inside and strain figures over a set's frames."""
    inside = np.concatenate(
        [100 * inside_fraction(c["seq"].garment_vertices, c["body"], c["collider"]) for c in clips]
    )
    strain = np.concatenate(
        [edge_strain(c["seq"].garment_vertices, template)[0].reshape(-1) for c in clips]
    )
    return {
        "inside_mean_pct": float(inside.mean()),
        "inside_p99_pct": float(np.percentile(inside, 99)),
        "strain_p50": float(np.median(strain)),
        "strain_p99": float(np.percentile(strain, 99)),
    }


def clip_renders(c: dict, img: Path, size: int, template) -> dict:
    """One clip rendered at its fastest turn and at its highest leg: simulation | ours |
    each baseline (seed 0), the whole body (arms too), coloured by error."""
    motion = c["seq"].motion
    leg, leg_height = highest_leg(c["feet_z"])
    frames = {"turn": fastest_turn(motion), "leg": leg}
    for what, frame in frames.items():
        picks = {
            label: c["garments"][key]["vertices"][frame]
            for label, key in (
                ("ours", "ours-full"),
                ("virtual bones", "virtual-bones"),
                ("Santesteban + push-out", "santesteban-push"),
            )
            if key in c["garments"]
        }
        path = img / f"results_{c['name']}_{what}.jpg"
        error_sheet(
            path,
            frame,
            c["seq"].garment_vertices,
            picks,
            c["body"],
            c["body_faces"],
            faces=template.faces,
            vmax=15.0,
            size=size,
            where=c["name"],
        )
    return {
        "turn": frames["turn"],
        "leg": frames["leg"],
        "leg_height_m": leg_height,
        "turn_rad_per_s": float(turn_rate(motion)[frames["turn"]]),
    }


# The cloth targets on every held-out clip (ours, the whole pipeline): key, text, test
CLOTH_TARGETS = [
    ("edge_change_p50", "median signed edge change within +-2 %", lambda r, s: abs(r) <= 0.02),
    ("strain_p50", "strain median within 3x the simulation's", lambda r, s: r <= 3 * s),
    ("flare_turn_error", "hem flare within 10 % of the simulation's over the 61 frames around "
     "the fastest turn", lambda r, s: r <= 0.10),
    ("inside_whole_max", "inside the whole body < 0.05 % of the vertices in every frame",
     lambda r, s: r < 0.0005),
    ("deep_whole_frames", "no frame deeper than 5 mm", lambda r, s: r == 0),
]  # fmt: skip


def cloth_figures(ours, c: dict, cache: Path) -> dict:
    """Ours (full) and the simulation on one clip: the stage account's figures (cached)."""
    path = cache / c["name"] / "cloth.json"
    if path.is_file():
        return json.loads(path.read_text())
    from loosefit.eval.stage_account import clip_reference

    measure, turn, window = clip_reference(ours, c["seq"])
    drop = ("flare_turn",)
    out = {
        "turn": turn,
        "window": list(window),
        "ours": {
            k: v
            for k, v in measure(c["garments"]["ours-full"]["vertices"]).items()
            if k not in drop
        },
        "simulation": {
            k: v for k, v in measure(c["seq"].garment_vertices).items() if k not in drop
        },
    }
    path.write_text(json.dumps(out))
    return out


def cloth_section(cloth: dict) -> list[str]:
    """The cloth targets, clip by clip: ours (full) against the simulation."""
    lines = [
        "## The cloth on every held-out clip",
        "",
        "Ours (the whole pipeline) and the simulation, measured as "
        "`bench/quality/stage_account.py` measures (the waistband's own edges left out of the "
        "strain; flare: the hem's mean distance from the pelvis's vertical axis, the mean of "
        "|ours / simulation - 1| frame by frame over the 61 frames around the clip's fastest "
        "turn; inside: the whole body, arms and hands included).",
        "",
        "| clip | edge change p50 % (sim) | strain p50 (sim) | flare error at the turn % | "
        "inside mean % | inside worst frame % (sim) | frames > 5 mm (sim) | deepest cm |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    misses = []
    for name, f in cloth.items():
        r, s = f["ours"], f["simulation"]
        lines.append(
            f"| {name} | {100 * r['edge_change_p50']:+.1f} ({100 * s['edge_change_p50']:+.1f}) | "
            f"{r['strain_p50']:.3f} ({s['strain_p50']:.3f}) | {100 * r['flare_turn_error']:.1f} | "
            f"{100 * r['inside_whole_mean']:.3f} | {100 * r['inside_whole_max']:.2f} "
            f"({100 * s['inside_whole_max']:.2f}) | {r['deep_whole_frames']} "
            f"({s['deep_whole_frames']}) | {100 * r['deepest_whole_m']:.2f} |"
        )
        for key, text, ok in CLOTH_TARGETS:
            if not ok(r[key], s[key]):
                misses.append(f"{name}: {text}")
    lines += ["", "Targets: " + "; ".join(t for _, t, _ in CLOTH_TARGETS) + "."]
    lines += ["", "**Missed:** " + "; ".join(misses) + "." if misses else "All met.", ""]
    return lines


def match_reference(name: str, ref_seq, clips: dict) -> tuple[str, int, float, list] | None:
    """The held-out clip a reference simulation shares its motion with (by name: the clip's
    own, or the chain of its parts; else by motion): its name, the frames they share, the
    largest difference of their joint rotations and the joints that differ by over 1e-3 (the
    pose correction can turn an arm a little differently on a shorter clip)."""
    by_name = [n for n in clips if n in (name, f"chain_{name}")]
    best = None
    for clip in by_name or list(clips):
        a, b = ref_seq.motion.rotations, clips[clip]["seq"].motion.rotations
        if a.shape[1:] != b.shape[1:]:
            continue
        n = min(len(a), len(b))
        per_joint = np.abs(a[:n] - b[:n]).max(axis=(0, 2, 3))
        joints = [j for j, d in zip(ref_seq.motion.joint_names, per_joint, strict=True) if d > 1e-3]
        hit = (clip, n, float(per_joint.max()), joints)
        if best is None or len(hit[3]) < len(best[3]):
            best = hit
    if best is None or (not by_name and best[3]):
        return None
    return best


def reference_section(reference: Path, clips: dict, cache: Path, template) -> list[str]:
    """The physical reference: the same motion simulated again from another seed (a start
    0.1 mm apart), scored against the data set's simulation like every method, on the
    frames it covers."""
    ref = DatasetReader(reference, allow_incomplete=True)
    lines = [
        "## The physical reference: the simulation against itself",
        "",
        "Cloth is chaotic: the same motion simulated again with another seed (the "
        "cloth's start jittered by 0.1 mm; `loosefit simulate --config "
        "configs/reference_seed.yaml`) drifts from the first simulation. That second "
        "simulation, scored like every method against the first on the frames it "
        "covers, is the error no deterministic model can be expected to beat by much.",
        "",
    ]
    rows = []
    for path in sorted((reference / "sequences").glob("*.npz")):
        seq = ref.read(path.stem)
        hit = match_reference(path.stem, seq, clips)
        if hit is None:
            lines.append(f"- `{path.stem}`: no held-out clip has its motion; left out.")
            continue
        name, n, diff, joints = hit
        c = clips[name]
        out = cache / "scores" / f"reference-{path.stem}.json"
        if not out.is_file():

            def part(v, c=c, n=n) -> dict:
                return {
                    "vertices": v[:n],
                    "truth": c["seq"].garment_vertices[:n],
                    "body": c["body"][:n],
                    "collider": c["collider"],
                }

            scores = {"simulation, another seed": score([part(seq.garment_vertices)], template)}
            for key, g in c["garments"].items():  # by method key: labels may change
                scores[key] = score([part(g["vertices"])], template)
            out.write_text(json.dumps(scores))
        scores = json.loads(out.read_text())
        rows.append((name, n, diff, joints, scores))
    for name, n, diff, joints, scores in rows:
        same = (
            "the same motion"
            if not joints
            else "the same motion but for "
            + ", ".join(joints)
            + f" (up to {diff:.2f} in a rotation entry: the pose "
            "correction turns it a little differently on the shorter clip)"
        )
        lines += [
            f"### `{name}`, its first {n} frames",
            "",
            f"({same})",
            "",
            "| method | RMSE cm | Hausdorff cm | STED | RMSE / the reference's |",
            "|---|---:|---:|---:|---:|",
        ]
        base = scores["simulation, another seed"]["rmse_cm"]
        for key, s in scores.items():
            label = METHODS[key][0] if key in METHODS else key
            lines.append(
                f"| {label} | {s['rmse_cm']:.2f} | {s['hausdorff_cm']:.2f} | "
                f"{s['sted']:.4f} | {s['rmse_cm'] / base:.2f} |"
            )
        lines.append("")
    return lines


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", default="datasets/salsa")
    p.add_argument("--checkpoint", default="checkpoints/salsa/motion.pt", help="ours")
    p.add_argument(
        "--with-detail",
        default=None,
        help="ours with a detail stage, where the "
        "shipped set has none: a packaged set of the same motion stage with one",
    )
    p.add_argument("--baselines", default="runs/salsa/baselines")
    p.add_argument("--ablation", default="runs/salsa/ablation")
    p.add_argument("--cache", default="runs/salsa/results")
    p.add_argument("--out", default="docs/results/RESULTS.md")
    p.add_argument("--img", default="docs/img")
    p.add_argument("--size", type=int, default=320, help="pixels per view of the renders")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument(
        "--reference",
        default=None,
        help="a data set of held-out motion simulated again with another seed "
        "(the physical reference row)",
    )
    p.add_argument(
        "--ensemble",
        default=None,
        help="docs/results/ENSEMBLE.md (bench/quality/ensemble.py): "
        "every method against an ensemble of simulations, as a section",
    )
    p.add_argument(
        "--table1",
        default=None,
        help="Table 1's Markdown (bench/ablations/motion_ablation.py --table), included as a "
        "section",
    )
    p.add_argument(
        "--table2",
        default=None,
        help="Table 2's Markdown (bench/ablations/detail_collision.py --out), included as a "
        "section",
    )
    args = p.parse_args()
    torch.set_num_threads(args.threads)
    started = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    reader = DatasetReader(args.data)
    template = reader.template
    cache = Path(args.cache)
    ours = loosefit.load(args.checkpoint).model
    img = Path(args.img)
    img.mkdir(parents=True, exist_ok=True)
    sets, all_clips = {}, {}
    for key, names in heldout_sets(reader).items():
        clips = [clip_data(args, reader, n, cache, ours) for n in names]
        all_clips.update({c["name"]: c for c in clips})
        scores = {}
        (cache / "scores").mkdir(parents=True, exist_ok=True)
        present = [m for m in METHODS if all(m in c["garments"] for c in clips)]
        for method in present:
            path = cache / "scores" / f"{key}-{method}.json"
            if not path.is_file():
                parts = [
                    {
                        "vertices": c["garments"][method]["vertices"],
                        "truth": c["seq"].garment_vertices,
                        "body": c["body"],
                        "collider": c["collider"],
                        "fps": c["seq"].motion.fps,
                    }
                    for c in clips
                ]
                s = score(parts, template)
                s["frames_per_second"] = sum(c["garments"][method]["frames"] for c in clips) / sum(
                    c["garments"][method]["seconds"] for c in clips
                )
                path.write_text(json.dumps(s))
            scores[method] = json.loads(path.read_text())
            print(
                key,
                method,
                {
                    k: v
                    for k, v in scores[method].items()
                    if not k.endswith(("per_frame_cm", "per_clip_cm", "per_clip"))
                },
            )
        sim = cache / "scores" / f"{key}-simulation.json"
        if not sim.is_file():
            sim.write_text(json.dumps(simulation_scores(clips, template)))
        # the set's fastest turn: the clip and frame where the heading turns fastest
        rates = [turn_rate(c["seq"].motion) for c in clips]
        spins = [int(np.argmax(r)) for r in rates]
        best = int(np.argmax([r[f] for r, f in zip(rates, spins, strict=True)]))
        c, spin = clips[best], spins[best]
        plot_per_frame(
            img / f"results_rmse_per_frame_{key}.png",
            scores,
            names,
            spins,
            f"{SET_TITLES[key]}: RMSE of each method per frame",
        )
        picks = {
            label: c["garments"][k]["vertices"][spin]
            for label, k in (
                ("ours", "ours-full"),
                ("virtual bones", "virtual-bones"),
                ("Santesteban + push-out", "santesteban-push"),
            )
            if k in c["garments"]
        }
        error_sheet(
            img / f"results_spin_{key}.jpg",
            spin,
            c["seq"].garment_vertices,
            picks,
            c["body"],
            c["body_faces"],
            faces=template.faces,
            vmax=15.0,
            size=args.size,
            where=c["name"],
        )
        sets[key] = {
            "clips": names,
            "frames": [c["seq"].motion.num_frames for c in clips],
            "scores": scores,
            "simulation": json.loads(sim.read_text()),
            "turn": {"clip": c["name"], "frame": spin, "rad_per_s": float(rates[best][spin])},
        }
        if key == "chain":
            chain = c
    ablation_per_frame = {}
    if "chain" in sets:
        ablation_per_frame = ablation_figures(
            Path(args.ablation),
            cache,
            reader,
            chain["seq"],
            chain["body"],
            chain["body_faces"],
            sets["chain"]["turn"]["frame"],
            img,
            args.size,
        )
    reports = {
        k: json.loads(Path(args.baselines, k, "report.json").read_text())
        for k in ("santesteban", "virtual-bones", "santesteban-s1", "virtual-bones-s1")
        if Path(args.baselines, k, "report.json").is_file()
    }
    spin = sets["chain"]["turn"]["frame"] if "chain" in sets else 0
    cloth = {name: cloth_figures(ours, c, cache) for name, c in all_clips.items()}
    shown = {
        name: clip_renders(c, img, args.size, template)
        for name, c in all_clips.items()
        if name in BALLET_CLIPS
    }
    extra = targets_section(sets) + ensemble_section(args.ensemble) + clip_section(shown)
    extra += cloth_section(cloth)
    if args.reference:
        extra += reference_section(Path(args.reference), all_clips, cache, template)
    extra += included_tables(args.table1, args.table2)
    text = markdown(
        args.data,
        sets,
        reports,
        ablation_section(Path(args.ablation))
        + ablation_verdict(Path(args.ablation))
        + ablation_plots(ablation_per_frame, spin),
        started,
        extra,
    )
    Path(args.out).write_text(text)
    (cache / "results.json").write_text(json.dumps(sets))
    print(f"wrote {args.out}")


def verdicts(scores: dict, turn: dict, clips: list[str], around: int = 30) -> list[str]:
    """The target, read off a set's table: ours (full) below both baselines on RMSE,
    Hausdorff and STED; each metric a baseline wins is named, with the share of frames
    each method is ahead on and the error around the set's fastest turn."""
    ours = scores["ours-full"]
    i, spin = clips.index(turn["clip"]), turn["frame"]
    mine = np.concatenate([np.asarray(p) for p in ours["rmse_per_frame_cm"]])
    near = slice(max(spin - around, 0), spin + around + 1)
    lines = []
    for key in [k for k in METHODS if k.startswith(("santesteban", "virtual")) and k in scores]:
        b = scores[key]
        won = [
            m
            for m, k in (("RMSE", "rmse_cm"), ("Hausdorff", "hausdorff_cm"), ("STED", "sted"))
            if b[k] < ours[k]
        ]
        verdict = (
            f"**the baseline is better on {', '.join(won)}**"
            if won
            else ("ours is better on RMSE, Hausdorff and STED")
        )
        theirs = np.concatenate([np.asarray(p) for p in b["rmse_per_frame_cm"]])
        a, t = np.asarray(ours["rmse_per_frame_cm"][i]), np.asarray(b["rmse_per_frame_cm"][i])
        lines.append(
            f"- Against {METHODS[key][0]}: {verdict}; ours has the lower RMSE on "
            f"{100 * np.mean(mine < theirs):.0f} % of the frames; within {around} frames of the "
            f"fastest turn, RMSE {np.sqrt(np.mean(a[near] ** 2)):.2f} (ours) against "
            f"{np.sqrt(np.mean(t[near] ** 2)):.2f} cm."
        )
    return lines


def ablation_plots(per_frame: dict, spin: int) -> list[str]:
    """The ablation's figures, where they were made."""
    if not per_frame:
        return []
    return [
        "",
        "Each decoder's (seed 0) reconstruction error per frame over the chain, and at "
        f"its fastest turn (frame {spin}; colour scale 0-8 cm):",
        "",
        "![Reconstruction RMSE per frame by decoder](../img/results_ablation_per_frame.png)",
        "",
        "![The fastest turn reconstructed by each decoder](../img/results_ablation_spin.jpg)",
    ]


def gaps(ablation: Path) -> dict[str, float]:
    """Per decoder: test minus train RMSE (cm), the mean over its seeds."""
    out: dict[str, list[float]] = {}
    for report in sorted(ablation.glob("*/report.json")):
        r = json.loads(report.read_text())
        out.setdefault(report.parent.name.split("-s")[0], []).append(
            r["test"]["rmse_cm"] - r["train"]["rmse_cm"]
        )
    return {d: float(np.mean(v)) for d, v in out.items()}


def ablation_verdict(ablation: Path) -> list[str]:
    """Whether the decomposed model beats both ablations by more than the seeds' noise."""
    runs: dict[str, list[float]] = {}
    for report in ablation.glob("*/report.json"):
        decoder = report.parent.name.split("-s")[0]
        runs.setdefault(decoder, []).append(json.loads(report.read_text())["test"]["rmse_cm"])
    if "decomposed" not in runs:
        return []
    noise = max((np.ptp(v) / 2 for v in runs.values() if len(v) > 1), default=float("nan"))
    ours = float(np.mean(runs["decomposed"]))
    lines = [
        "",
        f"Run-to-run noise (half the largest spread of a decoder's test RMSE over its "
        f"seeds): {noise:.3f} cm. Generalisation gap (test minus train RMSE, mean over "
        "seeds): " + ", ".join(f"{d} {g:.2f} cm" for d, g in gaps(ablation).items()) + ".",
        "",
    ]
    for decoder in ("vertex", "ssdr"):
        if decoder in runs:
            gap = float(np.mean(runs[decoder])) - ours
            if gap > noise:
                ahead = "ahead by more than the noise"
            elif gap < -noise:
                ahead = "**behind it** by more than the noise"
            else:
                ahead = "**not** ahead by more than the noise"
            lines.append(
                f"- Decomposed against `{decoder}`: {gap:+.3f} cm of mean test RMSE ({ahead})."
            )
    return lines


def set_section(key: str, st: dict) -> list[str]:
    """One held-out set's Table 3, ratios, verdicts, plot and render."""
    scores, simulation, turn = st["scores"], st["simulation"], st["turn"]
    clips = ", ".join(f"`{n}` ({f} frames)" for n, f in zip(st["clips"], st["frames"], strict=True))
    lines = [
        f"## Table 3 on {SET_TITLES[key]}: {clips}",
        "",
        "Never seen in training; every method rolled out once from each clip's first "
        "frame on the same motion; the clips' frames pooled; lengths in cm; inside: % of "
        "the garment's vertices inside the body (the simulation's collider), mean and "
        "99th percentile over frames; strain: |edge length / rest length - 1|, median "
        "and 99th percentile over edges and frames.",
        "",
        "| method | RMSE | Hausdorff | STED | inside mean % | inside p99 % | strain p50 | "
        "strain p99 | frames/s |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for method, s in scores.items():
        lines.append(
            f"| {METHODS[method][0]} | {s['rmse_cm']:.2f} | {s['hausdorff_cm']:.2f} | "
            f"{s['sted']:.4f} | {s['inside_mean_pct']:.3f} | {s['inside_p99_pct']:.2f} | "
            f"{s['strain_p50']:.3f} | {s['strain_p99']:.3f} | {s['frames_per_second']:.0f} |"
        )
    lines.append(
        f"| simulation (Newton VBD) | 0 | 0 | 0 | {simulation['inside_mean_pct']:.3f} | "
        f"{simulation['inside_p99_pct']:.2f} | {simulation['strain_p50']:.3f} | "
        f"{simulation['strain_p99']:.3f} | - |"
    )
    if len(st["clips"]) > 1:
        lines += [
            "",
            "RMSE per clip (cm): "
            + "; ".join(
                f"{METHODS[m][0]}: " + ", ".join(f"{v:.2f}" for v in s["rmse_per_clip_cm"])
                for m, s in scores.items()
            )
            + ".",
        ]
    ours = scores["ours-full"]
    lines += [
        "",
        "Ours (the shipped pipeline) against each baseline (ratio < 1: ours is "
        "better); the paper's Table 3 gives 0.62 against Santesteban and 0.75 "
        "against virtual bones on RMSE:",
        "",
        "| against | RMSE | Hausdorff | STED | paper, RMSE |",
        "|---|---:|---:|---:|---:|",
    ]
    for method, base in (("santesteban-push", "santesteban"), ("virtual-bones", "virtual-bones")):
        seeds = [m for m in (method, f"{method}-s1") if m in scores]  # none: not trained
        for m in seeds:
            b = scores[m]
            lines.append(
                f"| {METHODS[m][0]} | {ours['rmse_cm'] / b['rmse_cm']:.2f} | "
                f"{ours['hausdorff_cm'] / b['hausdorff_cm']:.2f} | "
                f"{ours['sted'] / b['sted']:.2f} | {PAPER_RATIOS[base]} |"
            )
        if len(seeds) > 1:
            mean = {
                k: np.mean([scores[m][k] for m in seeds])
                for k in ("rmse_cm", "hausdorff_cm", "sted")
            }
            lines.append(
                f"| {METHODS[method][0]}, mean of the seeds | "
                f"{ours['rmse_cm'] / mean['rmse_cm']:.2f} | "
                f"{ours['hausdorff_cm'] / mean['hausdorff_cm']:.2f} | "
                f"{ours['sted'] / mean['sted']:.2f} | {PAPER_RATIOS[base]} |"
            )
    lines += [
        "",
        *verdicts(scores, turn, st["clips"]),
        "",
        f"![RMSE per frame on {SET_TITLES[key]}](../img/results_rmse_per_frame_{key}.png)",
        "",
        f"The set's fastest turn ({turn['clip']}, frame {turn['frame']}, "
        f"{turn['rad_per_s']:.1f} rad/s), per-vertex error to the simulation:",
        "",
        "![The fastest turn: simulation, ours, virtual bones, Santesteban]"
        f"(../img/results_spin_{key}.jpg)",
        "",
    ]
    return lines


def targets_section(sets: dict) -> list[str]:
    """The headline targets on the held-out sets: the chain's RMSE, ballet's against it."""
    if "chain" not in sets:
        return []
    chain = sets["chain"]["scores"]["ours-full"]["rmse_cm"]
    lines = [
        "## The targets, read off the tables below",
        "",
        f"- Held-out salsa chain, ours (full pipeline): RMSE {chain:.2f} cm "
        f"(target below 7.0: {'met' if chain < 7.0 else '**not met**'}).",
    ]
    if "ballet" in sets:
        st = sets["ballet"]["scores"]["ours-full"]
        worst = max(st["rmse_per_clip_cm"])
        lines.append(
            f"- Held-out ballet clips: RMSE {st['rmse_cm']:.2f} cm pooled, "
            + ", ".join(
                f"{n} {v:.2f}"
                for n, v in zip(sets["ballet"]["clips"], st["rmse_per_clip_cm"], strict=True)
            )
            + f" per clip; the worst {worst / chain:.2f}x the chain's (target within "
            f"1.3x: {'met' if worst <= 1.3 * chain else '**not met**'})."
        )
    return lines + [""]


def ensemble_section(path: str | None) -> list[str]:
    """bench/quality/ensemble.py's tables (docs/results/ENSEMBLE.md) as a section."""
    if path is None:
        return []
    from loosefit.eval.ensemble import SECTION

    text = Path(path).read_text().splitlines()
    body = [line for line in text if not line.startswith("# ")]
    return [SECTION, "", f"From [{Path(path).name}]({Path(path).name}).", *body, ""]


def included_tables(table1: str | None, table2: str | None) -> list[str]:
    """Tables 1 and 2 as their own scripts wrote them, each a section (their headings one
    level down)."""
    lines = []
    for path, title, how in (
        (
            table1,
            "Table 1: the motion encoder with and without the previous state",
            "`bench/ablations/motion_ablation.py`: the motion stage alone, rolled out from each "
            "held-out clip's first frame; iter-N is the RMSE over the first N frames",
        ),
        (
            table2,
            "Table 2: the detail module with and without its discriminator",
            "`bench/ablations/detail_collision.py`: each variant rolled out whole on each held-out "
            "clip, the edge-length stage after it, with and without collision handling",
        ),
    ):
        if path is None:
            continue
        text = Path(path).read_text().splitlines()
        body = [
            ("#" + line if line.startswith("#") else line)
            for line in text
            if not line.startswith("# ")
        ]
        lines += [
            f"## {title}",
            "",
            f"From [{Path(path).name}]({Path(path).name}) ({how}).",
            "",
            *body,
            "",
        ]
    return lines


def clip_section(shown: dict) -> list[str]:
    """Each held-out ballet clip at its fastest turn and at its highest leg."""
    if not shown:
        return []
    lines = [
        "## Each held-out ballet clip at its fastest turn and its highest leg",
        "",
        "Simulation | ours | virtual bones | Santesteban + push-out (seed 0), the "
        "whole body drawn, per-vertex distance to the simulation (0-15 cm).",
        "",
    ]
    for name, f in shown.items():
        lines += [
            f"`{name}`: the fastest turn at frame {f['turn']} "
            f"({f['turn_rad_per_s']:.1f} rad/s); the highest leg at frame {f['leg']} "
            f"(one foot {100 * f['leg_height_m']:.0f} cm above the other).",
            "",
            f"![{name} at its fastest turn](../img/results_{name}_turn.jpg)",
            "",
            f"![{name} at its highest leg](../img/results_{name}_leg.jpg)",
            "",
        ]
    return lines


def markdown(
    data: str, sets: dict, reports: dict, ablation: list[str], started: str, extra: list[str] = ()
) -> str:
    lines = [
        "# Results: every method against the simulation",
        "",
        f"Made by `bash scripts/results.sh` (which trains the baselines and the ablation's "
        f"models, then runs `bench/quality/results.py`) on `{data}`; this run started {started} on "
        f"{machine('cpu')}.",
        "",
        "How the baselines are built, and a reading of these figures (why the ratios are "
        "not the paper's): [BASELINES.md](BASELINES.md).",
        "",
    ]
    lines += list(extra)
    for key, st in sets.items():
        lines += set_section(key, st)
    lines += [
        "Training of the baselines (`loosefit train baseline --preset cpu --mirror`, "
        "the committed motion stage's data and epochs):",
        "",
        "| baseline | epochs | parameters | s/epoch | machine |",
        "|---|---:|---:|---:|---|",
    ]
    for key, r in reports.items():
        lines.append(
            f"| {key} | {r['epochs']} | {r['parameters']:,} | "
            f"{r['seconds_per_epoch']:.1f} | {r['machine']} |"
        )
    minutes = sum(r["epochs"] * r["seconds_per_epoch"] for r in reports.values()) / 60
    seeds = {k: r for k, r in reports.items() if k.endswith("-s1")}
    if seeds:
        lines += [
            "",
            "Run-to-run noise: each baseline's held-out rollouts (no post-process, "
            "every held-out clip) with a second training seed:",
            "",
            "| baseline | seed 0 RMSE | seed 1 RMSE | seed 0 STED | seed 1 STED |",
            "|---|---:|---:|---:|---:|",
        ]
        for key, r1 in seeds.items():
            r0 = reports[key.removesuffix("-s1")]
            lines.append(
                f"| {key.removesuffix('-s1')} | {r0['test']['rmse_cm']:.2f} | "
                f"{r1['test']['rmse_cm']:.2f} | {r0['test']['sted']:.4f} | "
                f"{r1['test']['sted']:.4f} |"
            )
    lines += [
        "",
        f"Their training loops took {minutes:.0f} min in all (one core each; the "
        "virtual-bones run's skinning decomposition and the evaluations come on "
        "top).",
    ]
    lines += [
        "",
        "## The generative model's ablation (Fig. 4)",
        "",
        "Reconstruction (encode, decode the posterior mean) of the held-out clips by "
        "each decoder, trained on the data set's training clips (`bench/"
        "generative_ablation.py`, cpu preset, the same epochs for every decoder), "
        "two seeds each:",
        "",
        *ablation,
        "",
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    main()
