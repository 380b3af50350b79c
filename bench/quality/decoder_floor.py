"""The decoder floor: how well a decoder can represent held-out simulated garments, against
the simulation's own chaos.

Per held-out clip of a corpus (its test split; the chain on the frames the other seeds
cover and whole), RMSE in cm (the RMS over frames of each frame's RMS vertex distance,
:func:`~loosefit.eval.metrics.rmse_per_frame`):

1. **The chaos floor**: the same motion simulated again from other seeds (``--seeds``: data
   sets of the held-out clips, each from one seed): the pairwise RMSE among the members
   (seed 0 = the corpus's clip cut to the member's length, then each seed's), on the frames
   they share; mean, least and greatest over the pairs, and half the mean (the target).
   A member that its own data set flagged and left out of its split (the simulation's
   quality gate) is left out here too; its figures go to the JSON.
2. **The oracle**: the shipped generative model's reconstruction of the corpus's clip (its
   encoder's code Z* decoded; ``AnimationModel.reconstruct``), and on the training clips
   pooled. ``--generative LABEL=CHECKPOINT`` adds other generative stages (a run's
   ``checkpoint.pt``; LABEL says how it was trained) on the same rows, to show what a
   recipe buys.
3. **Linear bases**: the PCA of the training split's garments (every ``--stride``-th frame;
   with ``--mirror``, each training clip mirrored left-right too, as the engine tier and the
   motion stage train), in two representations:

   * *root frame*: the garment in the body's root frame (translation and heading removed:
     the frames of the engine tier and the generative model,
     :func:`~loosefit.inference.rollout.motion_root_frames`);
   * *unposed*: the garment unposed by the inverse skinning that supervises the generative
     model's unposed decoder (:func:`~loosefit.geometry.inverse_skinning.unskin` with body
     seed points, the generative training's :class:`InverseSkinningConfig`), projected,
     then skinned back by the same frame's seed frames.

   Basis: :func:`~loosefit.model.engine.fit_basis` (the engine tier's randomized SVD, double
   precision) with the largest K; each smaller K is its leading directions. The error of a
   held-out clip is that of its projection onto the first K directions: the best any
   decoder whose output lies in that subspace could do. ``--train-error`` adds the same on
   the training clips (unmirrored), to tell capacity from over-fitting.

    OMP_NUM_THREADS=1 python bench/quality/decoder_floor.py --data datasets/dance \\
        --seeds datasets/dance-seeds --checkpoint checkpoints/dance/motion.pt \\
        --train-error --out docs/results/DECODER_FLOOR.md

Writes the Markdown and the figures as JSON in bench/figures/.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import platform
import shlex
import time
from pathlib import Path

import numpy as np
import torch

import loosefit
from loosefit.api.generative import open_generative
from loosefit.data.format import DatasetReader
from loosefit.eval.metrics import rmse_per_frame, sted
from loosefit.geometry.inverse_skinning import InverseSkinningConfig, seed_weights, skin, unskin
from loosefit.inference.rollout import motion_root_frames
from loosefit.inference.timeline import RolloutConfig
from loosefit.model.engine import fit_basis, project, reconstruct
from loosefit.model.motion_features import from_root_frame, to_root_frame
from loosefit.train.clips import clip_versions
from loosefit.train.frames import avatar_for

# the figures of a page docs/X.md as JSON: bench/figures/X.json
FIGURES = Path(__file__).resolve().parents[1] / "figures"


KS = (32, 64, 128, 256, 512)
REPRESENTATIONS = ("root frame", "unposed")
PHRASE = {"root frame": "in the root frame", "unposed": "unposed by inverse skinning"}
CHAIN_PREFIX = "chain_"  # the corpus names a chained clip chain_A_B...; a seed set A_B...


def rms(per_frame_cm: np.ndarray) -> float:
    """The RMS over frames of per-frame RMSEs (cm)."""
    return float(np.sqrt(np.mean(np.asarray(per_frame_cm) ** 2)))


class Representation:
    """Garments to and from the two spaces a basis is fitted in.

    ``forward(name, motion, world)`` gives the clip's garments (T, V, 3) in the space and a
    ``back`` function that takes garments of that space to the world.
    """

    def __init__(self, reader: DatasetReader, floor: float):
        self.floor = floor
        self.config = RolloutConfig()
        self.avatar = avatar_for(reader)
        skinning = InverseSkinningConfig()
        self.seeds = self.avatar.seed_points(skinning.num_seeds)
        template = torch.from_numpy(reader.template.vertices)
        self.weights = seed_weights(template, self.seeds.rest.float().cpu(), skinning.temperature)[
            None
        ]  # (1, V, m)

    @torch.no_grad()
    def root_frame(self, motion, world: np.ndarray):
        H, p, _ = motion_root_frames(motion, self.floor, self.config)
        x = to_root_frame(torch.as_tensor(world, dtype=torch.float32), H, p)
        return x, lambda y: from_root_frame(y, H, p)

    @torch.no_grad()
    def unposed(self, motion, world: np.ndarray):
        body = self.avatar.pose_motion(motion)
        R, t = (a.float().cpu() for a in self.avatar.seed_frames(self.seeds, body))
        x = unskin(torch.as_tensor(world, dtype=torch.float32), self.weights, R, t)
        return x, lambda y: skin(y, self.weights, R, t)

    def __call__(self, kind: str, motion, world: np.ndarray):
        if kind == "root frame":
            return self.root_frame(motion, world)
        return self.unposed(motion, world)


def member_reader(root: Path) -> tuple[DatasetReader, dict]:
    reader = DatasetReader(root)
    return reader, json.loads((root / "manifest.json").read_text())


def reconstruction_errors(
    reconstruct, reader: DatasetReader, clips: list[str], steds: dict | None = None
) -> dict:
    """Each clip's per-frame reconstruction RMSE (T,) in cm; ``reconstruct(motion, garment)``
    gives the garment (T, V, 3) through a generative model. ``steds``: also each clip's
    STED against the simulation (the surface's roughness and jitter), written there."""
    out = {}
    for clip in clips:
        seq = reader.read(clip)
        rec = reconstruct(seq.motion, seq.garment_vertices)
        out[clip] = 100 * rmse_per_frame(rec, seq.garment_vertices)
        if steds is not None:
            steds[clip] = sted(np.asarray(rec), seq.garment_vertices, reader.template.faces)["sted"]
    return out


def generative_recipe(checkpoint: Path) -> str | None:
    """How a generative run's checkpoint was trained, in words (its ``config.json`` beside
    it, the epochs the checkpoint holds); None without the file."""
    path = checkpoint.parent / "config.json"
    if not path.is_file():
        return None
    t = json.loads(path.read_text())["train"]
    epochs = torch.load(checkpoint, map_location="cpu", weights_only=False).get("epoch")
    decoder = t["model"]["decoder"]
    unused = {"length_scale"} | ({"unposed", "template"} if decoder != "decomposed" else set())
    loss = ", ".join(f"{k} {v:g}" for k, v in t["loss"].items() if k not in unused)
    start = f"from `{t['init']}`" if t.get("init") else "from scratch"
    if decoder == "basis":
        k = t["model"]["basis_size"]
        start = f"of decoder basis ({k} directions) from its start, the projection"
    elif decoder != "decomposed" and not t.get("init"):
        start = f"of decoder {decoder} from scratch"
    data = "; every training clip also mirrored" if t.get("mirror") else ""
    return f"{epochs} epochs {start}, lr {t['lr']:g}, batch {t['batch_size']}{data}; loss: {loss}"


def pooled_sted(steds: dict | None, errors: dict) -> float | None:
    """The clips' STED, weighted by their frames; None where not measured."""
    if not steds:
        return None
    n = {c: len(errors[c]) for c in steds}
    return float(sum(steds[c] * n[c] for c in steds) / sum(n.values()))


def chaos_floor(reader: DatasetReader, seeds_root: Path | None, clip: str, frames: int | None):
    """The pairwise RMSE (cm) among a clip's members on their shared frames.

    Returns:
        dict: members (label -> frames), pairs (label pair -> cm), mean/min/max, the frames
        shared, and the same over the members a seed's data set flagged (``flagged``).
    """
    truth = reader.read(clip).garment_vertices
    members = {"seed 0": truth}
    flagged = {}
    short = clip[len(CHAIN_PREFIX) :] if clip.startswith(CHAIN_PREFIX) else clip
    for d in sorted(seeds_root.iterdir()) if seeds_root else []:
        if not (d / "manifest.json").is_file():
            continue
        r, manifest = member_reader(d)
        entry = manifest["sequences"].get(short)
        if entry is None or not r.sequence_path(short).is_file():
            continue
        g = r.read(short).garment_vertices
        label = f"seed {manifest['config']['cloth']['seed']}"
        if short in manifest["split"].get("test", []) + manifest["split"].get("train", []):
            members[label] = g
        else:
            flagged[label] = (g, entry.get("reason", entry.get("status", "")))
    n = min(len(g) for g in [*members.values(), *(g for g, _ in flagged.values())])
    if frames is not None:
        n = min(n, frames)

    def pairs(group: dict) -> dict:
        return {
            f"{a} / {b}": rms(100 * rmse_per_frame(group[a][:n], group[b][:n]))
            for a, b in itertools.combinations(group, 2)
        }

    main = pairs(members)
    out = {
        "frames": n,
        "members": {k: len(v) for k, v in members.items()},
        "pairs_cm": main,
        "mean_cm": float(np.mean(list(main.values()))) if main else None,
        "min_cm": float(min(main.values())) if main else None,
        "max_cm": float(max(main.values())) if main else None,
        "median_cm": float(np.median(list(main.values()))) if main else None,
    }
    # the first second's share: how much of the spread is there from the start
    if main:
        first = [
            rms(100 * rmse_per_frame(members[a][: min(n, 30)], members[b][: min(n, 30)]))
            for a, b in itertools.combinations(members, 2)
        ]
        out["first_30_frames_mean_cm"] = float(np.mean(first))
    # the member farthest from the others, and the floor without it (a member that took
    # another branch of the chaos for part of the clip weighs on the mean)
    if len(members) > 2:
        away = {
            m: float(np.mean([v for pair, v in main.items() if m in pair.split(" / ")]))
            for m in members
        }
        far = max(away, key=away.get)
        rest = [v for pair, v in main.items() if far not in pair.split(" / ")]
        out["farthest_member"] = far
        out["farthest_member_mean_cm"] = away[far]
        out["mean_without_farthest_cm"] = float(np.mean(rest))
    out["target_cm"] = None if out["mean_cm"] is None else 0.5 * out["mean_cm"]
    out["strict_target_cm"] = None if out["min_cm"] is None else 0.5 * out["min_cm"]
    if flagged:
        every = {**members, **{k: g for k, (g, _) in flagged.items()}}
        allp = pairs(every)
        out["flagged"] = {
            "members": {k: reason for k, (_, reason) in flagged.items()},
            "pairs_cm": {k: v for k, v in allp.items() if k not in main},
            "mean_with_them_cm": float(np.mean(list(allp.values()))),
        }
    return out


def training_frames(reader, rep: Representation, stride: int, mirror: bool, log):
    """(N, V, 3) float32 training garments in each representation (every ``stride``-th
    frame; the mirrored clips too with ``mirror``), and the count of clips."""
    out = {k: [] for k in REPRESENTATIONS}
    clips = 0
    for _, motion, garment in clip_versions(reader, "train", None, mirror):
        for kind in REPRESENTATIONS:
            x, _ = rep(kind, motion, garment)
            out[kind].append(x[::stride].clone())
        clips += 1
    log(f"training frames: {clips} clips, {sum(len(x) for x in out['root frame'])} frames")
    return {k: torch.cat(v) for k, v in out.items()}, clips


@torch.no_grad()
def basis_errors(basis, kind, rep, motion, world: np.ndarray, ks) -> dict[int, np.ndarray]:
    """(T,) per-frame RMSE (cm) of the clip's projection onto the first K directions, each K."""
    x, back = rep(kind, motion, world)
    out = {}
    for k in ks:
        b = basis.basis[:k]
        y = reconstruct(project(x, basis.mean, b), basis.mean, b)
        out[k] = 100 * rmse_per_frame(back(y), world)
    return out


@torch.no_grad()
def exact_check(reader, rep: Representation, basis, args, ks, held_out) -> dict:
    """The root-frame PCA again by the eigendecomposition of the (3V, 3V) scatter matrix
    (double precision, no randomness), and the largest difference of any held-out clip's
    error at any K from the randomized basis's (cm, positive: the exact basis is better)."""
    x = []
    for _, motion, garment in clip_versions(reader, "train", None, args.mirror):
        x.append(rep.root_frame(motion, garment)[0][:: args.stride])
    x = torch.cat(x).flatten(1).double()  # (N, 3V)
    mean = x.mean(0)
    x -= mean
    _, vectors = torch.linalg.eigh(x.T @ x)  # ascending
    del x
    exact = vectors[:, -max(ks) :].flip(1).T.float().reshape(max(ks), -1, 3)  # (K, V, 3)
    mean = mean.view(-1, 3).float()
    gap = 0.0
    rows = {}
    for clip in held_out:
        seq = reader.read(clip)
        x, back = rep.root_frame(seq.motion, seq.garment_vertices)
        rows[clip] = {}
        for k in ks:
            y = reconstruct(project(x, mean, exact[:k]), mean, exact[:k])
            e_exact = rms(100 * rmse_per_frame(back(y), seq.garment_vertices))
            y = reconstruct(project(x, basis.mean, basis.basis[:k]), basis.mean, basis.basis[:k])
            e_rand = rms(100 * rmse_per_frame(back(y), seq.garment_vertices))
            rows[clip][str(k)] = {"exact_cm": e_exact, "randomized_cm": e_rand}
            gap = max(gap, e_rand - e_exact)
    return {"clips": rows, "largest_gap_cm": gap}


def machine_line(threads: int) -> str:
    return (
        f"{platform.machine()}, {os.cpu_count()} CPUs, torch {torch.__version__}, "
        f"{threads} thread{'s' if threads != 1 else ''}, cpu"
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", default="datasets/dance")
    p.add_argument(
        "--seeds",
        default="datasets/dance-seeds",
        help="a folder of data sets of the held-out clips, one per seed",
    )
    p.add_argument("--checkpoint", default="checkpoints/dance/motion.pt")
    p.add_argument("--ks", default=",".join(map(str, KS)))
    p.add_argument("--stride", type=int, default=1, help="every this many training frames")
    p.add_argument(
        "--no-mirror",
        dest="mirror",
        action="store_false",
        help="the training clips as they are, not also mirrored",
    )
    p.add_argument(
        "--generative",
        action="append",
        default=[],
        metavar="LABEL=CHECKPOINT",
        help="also this generative stage's reconstruction (a run's checkpoint.pt), LABEL "
        "saying how it was trained (repeat for more)",
    )
    p.add_argument(
        "--keep-generative",
        action="store_true",
        help="also keep the generative stages the page's figures (bench/figures/) already "
        "hold, measured by an earlier run, not measured again",
    )
    p.add_argument("--train-error", action="store_true", help="also the training clips' error")
    p.add_argument(
        "--check-exact",
        action="store_true",
        help="also the root-frame basis by an exact eigendecomposition, to bound "
        "the randomized SVD's shortfall on the held-out clips",
    )
    p.add_argument("--out", default="docs/results/DECODER_FLOOR.md")
    p.add_argument("--machine", default=None, help="the machine line in the doc")
    p.add_argument("--date", default=time.strftime("%Y-%m-%d"))
    args = p.parse_args()
    torch.set_num_threads(1)
    start = time.perf_counter()

    def log(msg: str) -> None:
        print(f"[{time.perf_counter() - start:7.1f} s] {msg}", flush=True)

    ks = sorted(int(k) for k in args.ks.split(","))
    reader = DatasetReader(args.data)
    floor = float(reader.body["floor_height"])
    seeds_root = Path(args.seeds) if args.seeds else None
    held_out = reader.training_clips("test")
    result = {
        "machine": args.machine or machine_line(torch.get_num_threads()),
        "date": args.date,
        "command": "OMP_NUM_THREADS=1 python bench/quality/decoder_floor.py "
        + shlex.join(os.sys.argv[1:]),
        "data": str(args.data),
        "seeds": str(args.seeds),
        "checkpoint": str(args.checkpoint),
        "ks": ks,
        "stride": args.stride,
        "mirror": args.mirror,
        "seconds": {},
        "clips": {},
    }

    # the rows: each held-out clip, the chain cut to the other seeds' frames too
    t0 = time.perf_counter()
    rows = {}
    for clip in held_out:
        seq = reader.read(clip)
        floor_all = chaos_floor(reader, seeds_root, clip, None)
        n = floor_all["frames"]
        if n < len(seq.garment_vertices):
            rows[f"{clip}, first {n}"] = (clip, n, floor_all)
            rows[f"{clip}, whole"] = (clip, len(seq.garment_vertices), floor_all)
        else:
            rows[clip] = (clip, len(seq.garment_vertices), floor_all)
    result["seconds"]["chaos floor"] = time.perf_counter() - t0
    log(f"chaos floor: {result['seconds']['chaos floor']:.1f} s")

    # the oracle: per frame, so one pass over each whole clip serves its cut rows too
    t0 = time.perf_counter()
    model = loosefit.load(args.checkpoint).model
    stages = {"the shipped generative model": lambda m, g: model.reconstruct(m, g).vertices}
    recipes = [spec.partition("=") for spec in args.generative]
    for label, eq, path in recipes:
        if not (label and eq and path):
            p.error(f"--generative takes LABEL=CHECKPOINT, found {label}{eq}{path!r}")
        gen = open_generative(path, args.data)
        stages[label] = lambda m, g, gen=gen: gen.reconstruct(m, g).sequence.garment_vertices
    train_clips = reader.training_clips("train")
    errors, trained, steds = {}, {}, {}
    for label, rec in stages.items():
        steds[label] = {} if recipes else None
        errors[label] = reconstruction_errors(rec, reader, held_out, steds[label])
        if recipes:  # the training clips only where the page sets stages side by side
            trained[label] = rms(
                np.concatenate(list(reconstruction_errors(rec, reader, train_clips).values()))
            )
    oracle = errors["the shipped generative model"]
    result["seconds"]["oracle"] = time.perf_counter() - t0
    log(f"oracle: {result['seconds']['oracle']:.1f} s")

    # the bases
    t0 = time.perf_counter()
    rep = Representation(reader, floor)
    frames, nclips = training_frames(reader, rep, args.stride, args.mirror, log)
    result["training"] = {"clips": nclips, "frames": int(len(frames["root frame"]))}
    result["seconds"]["training frames (root frames, inverse skinning)"] = time.perf_counter() - t0
    bases = {}
    result["explained_variance"] = {}
    for kind in REPRESENTATIONS:
        t0 = time.perf_counter()
        bases[kind] = fit_basis(frames[kind], max(ks))
        result["seconds"][f"basis, {kind}"] = time.perf_counter() - t0
        ev = torch.cumsum(bases[kind].explained.double(), 0)
        result["explained_variance"][kind] = {str(k): float(ev[k - 1]) for k in ks}
        log(f"basis {kind}: {result['seconds'][f'basis, {kind}']:.1f} s")
    del frames

    # skinning's round trip: the unposed representation loses nothing before projection
    seq = reader.read(held_out[0])
    x, back = rep("unposed", seq.motion, seq.garment_vertices)
    result["unposed_round_trip_cm"] = float(
        100 * rmse_per_frame(back(x), seq.garment_vertices).max()
    )

    t0 = time.perf_counter()
    per_clip = {}
    for clip in held_out:
        seq = reader.read(clip)
        per_clip[clip] = {
            kind: basis_errors(bases[kind], kind, rep, seq.motion, seq.garment_vertices, ks)
            for kind in REPRESENTATIONS
        }
    result["seconds"]["held-out projections"] = time.perf_counter() - t0
    log(f"held-out projections: {result['seconds']['held-out projections']:.1f} s")

    for label, (clip, n, fl) in rows.items():
        row = {
            "clip": clip,
            "frames": n,
            "chaos": fl,
            "oracle_cm": rms(oracle[clip][:n]),
            "bases_cm": {
                kind: {str(k): rms(per_clip[clip][kind][k][:n]) for k in ks}
                for kind in REPRESENTATIONS
            },
        }
        for key, name in (("target_cm", "reaches_target"), ("strict_target_cm", "reaches_strict")):
            target = fl[key]
            row[name] = {
                "oracle": bool(row["oracle_cm"] <= target),
                **{
                    kind: {k: bool(v <= target) for k, v in row["bases_cm"][kind].items()}
                    for kind in REPRESENTATIONS
                },
            }
        result["clips"][label] = row

    # the oracle pooled over the held-out clips, whole (frame-weighted), as Table 1 pools
    cat = np.concatenate([oracle[c] for c in held_out])
    result["oracle_pooled_cm"] = rms(cat)
    result["oracle_pooled_frames"] = int(len(cat))
    result["generative_stages"] = {
        label: {
            "checkpoint": args.checkpoint if i == 0 else recipes[i - 1][2],
            "train_cm": trained.get(label),
            "held_out_pooled_cm": rms(np.concatenate([errors[label][c] for c in held_out])),
            "rows_cm": {row: rms(errors[label][clip][:n]) for row, (clip, n, _) in rows.items()},
            "recipe": None if i == 0 else generative_recipe(Path(recipes[i - 1][2])),
            "held_out_sted": pooled_sted(steds[label], errors[label]),
            "measured": args.date,
        }
        for i, label in enumerate(stages)
    }
    if args.keep_generative:  # earlier runs' stages, not measured again (their checkpoints
        # may be gone), after the shipped one and before this run's; marked with their date
        before = json.loads((FIGURES / f"{Path(args.out).stem}.json").read_text())
        stages_now = result["generative_stages"]
        shipped = next(iter(stages_now))
        kept = {}
        for label, g in before.get("generative_stages", {}).items():
            if label not in stages_now:
                if set(g["rows_cm"]) != set(rows):
                    p.error(f"--keep-generative: {label!r} was measured on other rows")
                kept[label] = {"measured": before["date"], **g}
        result["generative_stages"] = {
            shipped: stages_now[shipped],
            **kept,
            **{k: v for k, v in stages_now.items() if k != shipped},
        }

    # the least K of each representation that reaches the target on every row (and the
    # strict one: half the closest pair of seeds)
    for name in ("reaches_target", "reaches_strict"):
        least = result[f"least_k_everywhere_{name}"] = {}
        for kind in REPRESENTATIONS:
            ok = [k for k in ks if all(r[name][kind][str(k)] for r in result["clips"].values())]
            least[kind] = ok[0] if ok else None
        result[f"oracle_everywhere_{name}"] = all(
            r[name]["oracle"] for r in result["clips"].values()
        )

    if args.check_exact:
        t0 = time.perf_counter()
        result["exact_check"] = exact_check(reader, rep, bases["root frame"], args, ks, held_out)
        result["seconds"]["exact check"] = time.perf_counter() - t0
        log(f"exact check: {result['seconds']['exact check']:.1f} s")

    if args.train_error:
        t0 = time.perf_counter()
        sq = {kind: {k: 0.0 for k in ks} for kind in REPRESENTATIONS}
        count = 0
        worst = {kind: {k: 0.0 for k in ks} for kind in REPRESENTATIONS}
        for _, motion, garment in clip_versions(reader, "train", None, False):
            for kind in REPRESENTATIONS:
                errs = basis_errors(bases[kind], kind, rep, motion, garment, ks)
                for k in ks:
                    sq[kind][k] += float((errs[k] ** 2).sum())
                    worst[kind][k] = max(worst[kind][k], rms(errs[k]))
            count += len(garment)
        result["train_cm"] = {
            kind: {str(k): float(np.sqrt(sq[kind][k] / count)) for k in ks}
            for kind in REPRESENTATIONS
        }
        result["train_worst_clip_cm"] = {
            kind: {str(k): worst[kind][k] for k in ks} for kind in REPRESENTATIONS
        }
        result["train_frames"] = count
        result["train_clips"] = len(reader.training_clips("train"))
        result["seconds"]["training projections"] = time.perf_counter() - t0
        log(f"training projections: {result['seconds']['training projections']:.1f} s")

    result["seconds"]["total"] = time.perf_counter() - start
    out = Path(args.out)
    (FIGURES / f"{out.stem}.json").write_text(json.dumps(result, indent=1) + "\n")
    out.write_text(markdown(result))
    print(out.read_text())


def _least(r: dict, name: str, kind: str) -> str:
    k = r[f"least_k_everywhere_{name}"][kind]
    return f"K = {k}" if k is not None else f"no K up to {max(r['ks'])}"


def markdown(r: dict) -> str:
    ks, clips = r["ks"], r["clips"]
    stride = "every training frame" if r["stride"] == 1 else f"every {r['stride']}th training frame"
    mirrored = ", each clip also mirrored left-right" if r["mirror"] else ", not mirrored"
    lines = [
        "# The decoder floor: held-out garments through a decoder, against the simulation's chaos",
        "",
        f"Machine: {r['machine']}; {r['date']}. Written by `{r['command']}` in "
        f"{r['seconds']['total'] / 60:.1f} minutes (`bench/quality/decoder_floor.py`).",
        "",
        "How closely can a decoder reproduce a held-out simulated garment, set beside how far "
        "the simulation lands from itself when the same motion is simulated again from another "
        "seed? The target under study: on every held-out clip, the decoder's reconstruction "
        "at most half that clip's chaos floor. RMSE throughout: the RMS over frames of each "
        "frame's RMS vertex distance, in cm (`loosefit.eval.metrics.rmse_per_frame`).",
        "",
        "## The chaos floor",
        "",
        "The members of a clip: the corpus's simulation (seed 0) cut to the other seeds' "
        f"length, and the same motion simulated again from seeds 1-3 (`{r['seeds']}`). The "
        "floor is the pairwise RMSE among the members on the frames they share: their mean "
        "(the chaos floor), least, median and greatest; the target is half the mean, the "
        "strict target half the least pair. The first second: the mean pairwise RMSE over "
        "the first 30 frames (each seed settles its own drape, so the members differ from "
        "the first frame).",
        "",
        "| clip | frames shared | members | mean | least | median | greatest | first second "
        "| target: 0.5x mean | strict: 0.5x least |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    seen = set()
    notes = []
    for row in clips.values():
        c = row["chaos"]
        if row["clip"] in seen:
            continue
        seen.add(row["clip"])
        lines.append(
            f"| {row['clip']} | {c['frames']} | {len(c['members'])} | {c['mean_cm']:.2f} | "
            f"{c['min_cm']:.2f} | {c['median_cm']:.2f} | {c['max_cm']:.2f} | "
            f"{c['first_30_frames_mean_cm']:.2f} | {c['target_cm']:.2f} | "
            f"{c['strict_target_cm']:.2f} |"
        )
        if "flagged" in c:
            f = c["flagged"]
            for label, reason in f["members"].items():
                notes.append(
                    f"{row['clip']}: {label} is left out: its data set flagged it ({reason}) "
                    f"and left it out of its split. With it the mean would be "
                    f"{f['mean_with_them_cm']:.2f} cm (its pairs: "
                    + ", ".join(f"{v:.2f}" for v in f["pairs_cm"].values())
                    + ")."
                )
        pairs = c["pairs_cm"]
        if pairs and c["max_cm"] > 2 * c["min_cm"] and "farthest_member" in c:
            notes.append(
                f"{row['clip']}: the pairs spread from {c['min_cm']:.2f} to {c['max_cm']:.2f} "
                f"cm. One member, {c['farthest_member']}, lies {c['farthest_member_mean_cm']:.2f}"
                f" cm from the others on average; without it the mean is "
                f"{c['mean_without_farthest_cm']:.2f} cm (target "
                f"{0.5 * c['mean_without_farthest_cm']:.2f})."
            )
    lines += [""] + [f"- {n}" for n in notes] + [""]

    lines += [
        "## Reconstructions of the held-out clips",
        "",
        "The oracle: the shipped generative model's reconstruction of the corpus's clip (the "
        f"encoder's code decoded; `{r['checkpoint']}`, `reconstruct`). Linear bases: the PCA "
        f"of the training split's garments ({r['training']['clips']} clips, "
        f"{r['training']['frames']} frames: {stride}{mirrored}, as the engine tier trains), "
        "the held-out garment projected onto its first K directions: the least error of any "
        "decoder whose output lies in that span. *Root frame*: the garment with the body's "
        "translation and heading removed (the engine tier's and the generative model's frame). "
        "*Unposed*: the garment unposed by the inverse skinning that supervises the generative "
        "model's unposed decoder (256 body seed points, temperature 5 cm), projected, and "
        "skinned back by the same frame's seed frames (the round trip alone loses "
        f"{r['unposed_round_trip_cm']:.1e} cm). Bold: at most the target (half the chaos "
        "floor's mean). The chain's whole clip is held to the floor of the frames the other "
        "seeds cover.",
        "",
    ]
    for kind in REPRESENTATIONS:
        head = "| clip | frames | target | oracle |" + "".join(f" K={k} |" for k in ks)
        lines += [f"### {kind}", "", head, "|---|---:|---:|---:|" + "---:|" * len(ks)]
        for label, row in clips.items():
            t = row["chaos"]["target_cm"]

            def cell(v: float, t: float = t) -> str:
                return f"**{v:.2f}**" if v <= t else f"{v:.2f}"

            lines.append(
                f"| {label} | {row['frames']} | {t:.2f} | {cell(row['oracle_cm'])} |"
                + "".join(f" {cell(row['bases_cm'][kind][str(k)])} |" for k in ks)
            )
        lines.append("")
    ev = r["explained_variance"]
    lines += [
        "Share of the training frames' variance the first K directions hold: "
        + "; ".join(
            f"{kind}: " + ", ".join(f"{100 * ev[kind][str(k)]:.2f} % (K={k})" for k in ks)
            for kind in REPRESENTATIONS
        )
        + ".",
        "",
    ]
    gens = r.get("generative_stages", {})
    if len(gens) > 1:
        labels = list(clips)
        lines += [
            "### Generative stages",
            "",
            "Each generative stage's reconstruction (its encoder's code decoded) of the "
            "held-out clips and, pooled, of the training clips (unmirrored): what a recipe "
            "buys, and whether it is capacity or generalisation that it lacks. Bold: at most "
            "the target. STED: the held-out clips' reconstructions against the simulation "
            "(frame-weighted; the surface's roughness and jitter, which a decoder that "
            "fits closer can trade away). Measured: the date of the run that measured the "
            "row (`--keep-generative` keeps earlier rows).",
            "",
            "| generative stage | training clips | "
            + " | ".join(labels)
            + " | held-out, pooled | held-out STED | measured |",
            "|---|---:|" + "---:|" * len(labels) + "---:|---:|---|",
            "| target | | "
            + " | ".join(f"{clips[c]['chaos']['target_cm']:.2f}" for c in labels)
            + " | | | |",
        ]
        for label, g in gens.items():
            cells = [
                f"**{g['rows_cm'][c]:.2f}**"
                if g["rows_cm"][c] <= clips[c]["chaos"]["target_cm"]
                else f"{g['rows_cm'][c]:.2f}"
                for c in labels
            ]
            st = g.get("held_out_sted")
            lines.append(
                f"| {label} | {g['train_cm']:.2f} | "
                + " | ".join(cells)
                + f" | {g['held_out_pooled_cm']:.2f} | "
                + ("-" if st is None else f"{st:.4f}")
                + f" | {g.get('measured', r['date'])} |"
            )
        lines.append("")
        lines += [f"- {label}: {g['recipe']}." for label, g in gens.items() if g.get("recipe")]
        lines.append("")
    if "train_cm" in r:
        lines += [
            "### The same bases on the training clips",
            "",
            f"Every frame of the {r['train_clips']} training clips, unmirrored "
            f"({r['train_frames']} frames), projected as above: "
            "all frames pooled, and the worst clip.",
            "",
            "| representation | " + " | ".join(f"K={k}" for k in ks) + " |",
            "|---|" + "---:|" * len(ks),
        ]
        for kind in REPRESENTATIONS:
            lines.append(
                f"| {kind}, pooled | "
                + " | ".join(f"{r['train_cm'][kind][str(k)]:.2f}" for k in ks)
                + " |"
            )
            lines.append(
                f"| {kind}, worst clip | "
                + " | ".join(f"{r['train_worst_clip_cm'][kind][str(k)]:.2f}" for k in ks)
                + " |"
            )
        lines.append("")
    if "exact_check" in r:
        lines += [
            f"The bases come from the engine tier's randomized SVD (`fit_basis`). Checked "
            "against an exact eigendecomposition of the root-frame scatter matrix: no held-out "
            f"clip's error at any K is more than {r['exact_check']['largest_gap_cm']:.3f} cm "
            "above the exact basis's.",
            "",
        ]

    # what it means for the target
    lines += ["## What it means for the target", ""]
    miss = [
        f"{label} ({row['oracle_cm']:.2f} cm against {row['chaos']['target_cm']:.2f}, "
        f"{row['oracle_cm'] / row['chaos']['target_cm']:.2f}x)"
        for label, row in clips.items()
        if not row["reaches_target"]["oracle"]
    ]
    hit = [label for label, row in clips.items() if row["reaches_target"]["oracle"]]
    if miss:
        lines.append(
            "- The shipped generative model does not reach it: its reconstruction misses the "
            "target on "
            + "; ".join(miss)
            + (f"; it reaches it on {' and '.join(hit)}." if hit else ".")
        )
    else:
        lines.append("- The shipped generative model's reconstruction reaches it on every clip.")
    for label, g in list(r.get("generative_stages", {}).items())[1:]:
        ratio = {c: g["rows_cm"][c] / clips[c]["chaos"]["target_cm"] / 2 for c in clips}
        worst = max(ratio, key=ratio.get)
        if all(g["rows_cm"][c] <= clips[c]["chaos"]["target_cm"] for c in clips):
            lines.append(
                f"- {label} reaches it on every clip: at most {ratio[worst]:.2f}x the chaos "
                f"floor ({worst})."
            )
    for kind in REPRESENTATIONS:
        k = r["least_k_everywhere_reaches_target"][kind]
        line = (
            f"- A linear basis, {PHRASE[kind]}, reaches it on every clip from "
            f"{_least(r, 'reaches_target', kind)}"
        )
        if k is not None:
            worst = max(
                clips.values(),
                key=lambda row, k=k: row["bases_cm"][kind][str(k)] / row["chaos"]["target_cm"],
            )
            line += (
                f" (its tightest clip: {worst['clip']}, "
                f"{worst['bases_cm'][kind][str(k)]:.2f} cm against "
                f"{worst['chaos']['target_cm']:.2f})"
            )
            smaller = [q for q in ks if q < k]
            if smaller:
                q = smaller[-1]
                misses = [
                    f"{label} {row['bases_cm'][kind][str(q)]:.2f} > {row['chaos']['target_cm']:.2f}"
                    for label, row in clips.items()
                    if not row["reaches_target"][kind][str(q)]
                ]
                line += f"; at K = {q} it misses " + ", ".join(misses)
        line += (
            f". Against the strict target (half the closest pair): "
            f"{_least(r, 'reaches_strict', kind)}."
        )
        lines.append(line)
    strict_oracle = [lab for lab, row in clips.items() if row["reaches_strict"]["oracle"]]
    lines.append(
        "- Against the strict target (half the closest pair) the shipped generative model "
        + (
            f"reaches it on {', '.join(strict_oracle)} only."
            if strict_oracle
            else "misses every clip."
        )
    )
    for label, row in clips.items():
        c = row["chaos"]
        if not (c["max_cm"] > 2 * c["min_cm"] and "farthest_member" in c):
            continue
        t = 0.5 * c["mean_without_farthest_cm"]
        ok = [k for k in ks if row["bases_cm"]["root frame"][str(k)] <= t]
        lines.append(
            f"- {label}: held to the floor without {c['farthest_member']} (target {t:.2f} "
            f"cm), the oracle ({row['oracle_cm']:.2f}) "
            + ("reaches it" if row["oracle_cm"] <= t else "misses it")
            + "; a root-frame basis reaches it "
            + (f"from K = {ok[0]}." if ok else f"at no K up to {ks[-1]}.")
        )
    k0 = r["least_k_everywhere_reaches_target"]["root frame"]
    diff = max(
        abs(row["bases_cm"]["root frame"][str(k)] - row["bases_cm"]["unposed"][str(k)])
        for row in clips.values()
        for k in ks
    )
    lines.append(
        f"- Unposing buys a linear basis nothing here: the two representations' held-out "
        f"errors differ by at most {diff:.2f} cm at any K on any clip."
        if diff < 0.15
        else f"- The two representations' held-out errors differ by up to {diff:.2f} cm."
    )
    if "train_cm" in r:
        tr = r["train_cm"]["root frame"]

        def ratios(k: int) -> str:
            q = [row["bases_cm"]["root frame"][str(k)] / tr[str(k)] for row in clips.values()]
            return f"{min(q):.2f}-{max(q):.2f} at K = {k}"

        falls = all(
            row["bases_cm"][kind][str(a)] > row["bases_cm"][kind][str(b)]
            for row in clips.values()
            for kind in REPRESENTATIONS
            for a, b in itertools.pairwise(ks)
        )
        lines.append(
            "- Held-out against training (root frame): each held-out clip's error over the "
            f"training clips' pooled error is {ratios(ks[0])} and {ratios(ks[-1])} (training: "
            f"{', '.join(f'{tr[str(k)]:.2f}' for k in ks)} cm at K = {', '.join(map(str, ks))})"
            + (
                f"; it falls with every K on every held-out clip up to K = {ks[-1]}: the "
                "directions that the training frames add keep helping the held-out clips, "
                "if a little less than the training clips themselves."
                if falls
                else "."
            )
        )
    lines.append(
        f"- The shipped generative model's reconstruction pooled over the held-out clips, "
        f"whole ({r['oracle_pooled_frames']} frames): {r['oracle_pooled_cm']:.2f} cm. The oracle "
        "row of the results' Table 1 (4.2 cm on the same clips) was measured on the "
        "generative model given to its ablation script (`bench/ablations/motion_ablation.py "
        "--generative`, a `cpu`-preset run), not on the shipped set."
    )
    if k0 is not None:
        o = [row["oracle_cm"] for row in clips.values()]
        b = [row["bases_cm"]["root frame"]["128"] for row in clips.values()] if 128 in ks else []
        if b:
            q = [o_ / b_ for o_, b_ in zip(o, b, strict=True)]
            lines.append(
                f"- The generative model's code has 128 numbers; a 128-direction root-frame "
                f"basis reconstructs the held-out clips to {min(b):.2f}-{max(b):.2f} cm where "
                f"the generative model reaches {min(o):.2f}-{max(o):.2f}: the shipped "
                f"decoder's error is {min(q):.1f}-{max(q):.1f}x that of the best linear "
                "decoder with as many numbers a frame."
            )
    lines.append("")

    lines += ["## Time", "", "| piece | seconds |", "|---|---:|"]
    lines += [f"| {k} | {v:.1f} |" for k, v in r["seconds"].items()]
    lines.append("")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
