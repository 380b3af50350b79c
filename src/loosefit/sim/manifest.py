"""A data set's manifest: opened or begun, each clip's entry, clips taken from another data
set, and the migrations that keep a data set made by an older loosefit going.

A manifest stores the configuration it was made with. A field added since is read at the
value the data set was made with (:data:`LEGACY_CLOTH`, :data:`LEGACY_UNFOLD`, else its
default), and a change of the release of trapped cloth or of the pose correction alone
keeps the clips it leaves as they were (:func:`recheck_release`, :func:`recheck_unfold`).
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import importlib.metadata
import json
import os
import platform
import shutil
from dataclasses import asdict
from pathlib import Path

import numpy as np

from loosefit.atomic import atomic_path
from loosefit.data.format import FORMAT, write_json_atomic
from loosefit.errors import LoosefitInputError
from loosefit.garment.fingerprint import cloth_fingerprint
from loosefit.garment.quality import PENETRATION_TOLERANCE
from loosefit.motion.pose_correction import UnfoldConfig
from loosefit.sim.dataset_config import GARMENT_TYPES, DatasetConfig, config_dict, normalized
from loosefit.sim.jobs import Job, job_motion, limb_parts, short_spec, split_member


def package_versions() -> dict[str, str]:
    """Versions of the packages that decide a dataset's content."""
    out = {"python": platform.python_version()}
    for pkg in ("loosefit", "torch", "newton", "warp-lang", "anny", "numpy"):
        try:
            out[pkg] = importlib.metadata.version(pkg)
        except importlib.metadata.PackageNotFoundError:
            out[pkg] = "not installed"
    return out


# Cloth fields whose default changed what is simulated: a data set whose manifest lacks one
# was made with this value (not the default).
LEGACY_CLOTH = {
    "flatten_overlaps": False,
    "overlap_inset": 0.002,
    "arm_friction": None,
    "release_depth": None,
}
# Cloth fields a clip can be rechecked for rather than simulated again when they change: the
# release of trapped cloth acts only where cloth is that deep, which a clip's frames show.
RELEASE_FIELDS = ("release_depth",)
LEGACY_UNFOLD = {
    "enabled": False
}  # the same for the pose correction (loosefit.motion.pose_correction)


def stored_config(manifest: dict) -> dict:
    """A manifest's configuration, with the fields added since it was written at their defaults.

    A dataset made before a field existed is the one made with its default value (or, for
    :data:`LEGACY_CLOTH`'s and :data:`LEGACY_UNFOLD`'s, the value it was made with).
    """

    def fill(old: dict, default: dict) -> dict:
        out = dict(old)
        for key, value in default.items():
            if key not in out:
                out[key] = value
            elif isinstance(value, dict) and isinstance(out[key], dict):
                out[key] = fill(out[key], value)
        return out

    stored = manifest.get("config", {})
    stored = {
        **stored,
        "cloth": {**LEGACY_CLOTH, **stored.get("cloth", {})},
        "unfold": {**LEGACY_UNFOLD, **stored.get("unfold", {})},
    }
    default = normalized(config_dict(DatasetConfig()))
    kind = stored.get("garment", {}).get("type", "skirt")
    if kind != "skirt" and kind in GARMENT_TYPES:  # fill a dress's fields from a dress's
        default["garment"] = normalized({"type": kind, **asdict(GARMENT_TYPES[kind]())})
    return fill(stored, default)


def refresh_fingerprints(manifest: dict, cloth: dict) -> None:
    """Entries of the manifest's cloth configuration as it was stored take its fingerprint
    with the fields added since at the values they were made with (``cloth``, from
    :func:`stored_config`): the same configuration, which the manifest is about to store."""
    before = cloth_fingerprint(manifest.get("config", {}).get("cloth", {}))
    after = cloth_fingerprint(cloth)
    for entry in manifest.get("sequences", {}).values():
        if entry.get("cloth_fingerprint") == before:
            entry["cloth_fingerprint"] = after


def open_manifest(config: DatasetConfig, out: Path) -> dict:
    """A new manifest, or the existing one of the same configuration (resume)."""
    mpath = out / "manifest.json"
    cfg = normalized(config_dict(config))
    if mpath.is_file():
        manifest = json.loads(mpath.read_text())
        old = stored_config(manifest)
        refresh_fingerprints(manifest, old["cloth"])
        # The device decides no more than the rounding: a data set begun on a GPU goes on on
        # the CPU and vice versa. Each clip's entry notes its device; the manifest's
        # configuration stays the first run's.
        first_device = old["cloth"].get("device", cfg["cloth"]["device"])
        old = {**old, "cloth": {**old["cloth"], "device": cfg["cloth"]["device"]}}
        # A change of the release of trapped cloth alone keeps the clips it never changed
        # (generate checks each; see recheck_release).
        net = {k: old["cloth"].get(k) for k in RELEASE_FIELDS}
        if old.get("cloth") != cfg.get("cloth") and {
            k: v for k, v in old["cloth"].items() if k not in RELEASE_FIELDS
        } == {k: v for k, v in cfg["cloth"].items() if k not in RELEASE_FIELDS}:
            old = {**old, "cloth": cfg["cloth"]}
            for entry in manifest["sequences"].values():
                for k, v in net.items():
                    entry.setdefault(k, v)
        # A change of the pose correction alone keeps the clips whose motion it leaves as it
        # was (generate checks each; see recheck_unfold): each entry notes what made it.
        if old.get("unfold") != cfg.get("unfold"):
            for entry in manifest["sequences"].values():
                entry.setdefault("unfold_config", old["unfold"])
            old = {**old, "unfold": cfg["unfold"]}
        if manifest.get("format") != FORMAT or old != cfg:
            diff = sorted(k for k in set(old) | set(cfg) if old.get(k) != cfg.get(k))
            raise LoosefitInputError(
                out,
                "manifest.json",
                f"an empty folder or a dataset of the same configuration (preset {config.preset})",
                f"another dataset (preset {manifest.get('preset')}; differs in {diff})",
                hint="choose another --out folder",
            )
        manifest["config"] = {**cfg, "cloth": {**cfg["cloth"], "device": first_device}}
        return manifest
    if out.exists() and any(out.iterdir()):
        raise LoosefitInputError(
            out, "<folder>", "an empty or new folder", f"{len(list(out.iterdir()))} other entries"
        )
    return {
        "format": FORMAT,
        "preset": config.preset,
        "complete": False,
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "config": cfg,
        "versions": package_versions(),
        "machine": {
            "platform": platform.platform(),
            "processor": platform.processor(),
            "cpu_count": os.cpu_count(),
        },
        "sequences": {},
        "split": {"train": [], "test": []},
    }


def _same_value(field: str, theirs, ours) -> bool:
    """Whether two data sets' motion fields agree; a folder is compared as the folder it
    names (``../shared/mocap/x`` and its absolute path are one folder)."""
    if field == "folder" and theirs and ours:
        return Path(theirs).resolve() == Path(ours).resolve()
    return theirs == ours


def adopt_clips(
    config: DatasetConfig, jobs: list[Job], manifest: dict, out: Path, source: Path
) -> list[str]:
    """Take the clips ``jobs`` share with another dataset from it instead of simulating them.

    A clip is taken when the other dataset simulated it with the same garment,
    cloth, body, frame rate and seed, from the same motion (spec, seed and frame
    range) and the same jitter seed: its sequence is hard-linked (copied across file
    systems) and its manifest entry copied, marked with where it came from. The ensembles
    (``seeds``) may differ: an ensemble takes the members another holds (its own clips,
    from a data set of none), its entries noting this one's :func:`member_fields`. A clip
    flagged there is taken as flagged (the simulation is deterministic).

    Args:
        config: this dataset's configuration.
        jobs: this dataset's clips.
        manifest: this dataset's manifest (updated in place).
        out: this dataset's folder.
        source: the other dataset's folder.

    Returns:
        The names of the clips taken.
    """
    mpath = source / "manifest.json"
    if not mpath.is_file():
        raise LoosefitInputError(
            source, "manifest.json", "a dataset folder to reuse clips from", "no manifest.json"
        )
    other = json.loads(mpath.read_text())
    theirs = stored_config(other)
    ours = normalized(config_dict(config))
    their_device = theirs["cloth"].get("device")
    theirs = {**theirs, "cloth": {**theirs["cloth"], "device": ours["cloth"]["device"]}}
    same = ("garment", "cloth", "unfold", "limits", "fps", "seed", "shape")
    clip = ("kind", "folder", "max_frames", "start_frame")
    differs = [k for k in same if theirs.get(k) != ours.get(k)]
    differs += [
        f"motions.{k}"
        for k in clip
        if not _same_value(k, theirs["motions"].get(k), ours["motions"][k])
    ]
    if other.get("format") != FORMAT or differs:
        raise LoosefitInputError(
            source,
            "manifest.json",
            "a dataset simulated like this one (garment, cloth, body, rate, seed, clip range)",
            f"one that differs in {differs or ['format']}",
        )
    taken = []
    for job in jobs:
        entry = other["sequences"].get(job.name)
        if job.name in manifest["sequences"] or entry is None:
            continue
        if (
            entry.get("spec") != short_spec(job.spec)
            or entry.get("seed") != job.jitter_seed
            or entry.get("motion_seed", entry.get("seed")) != job.seed
            or entry.get("test") != job.test
        ):
            continue
        src = source / "sequences" / f"{job.name}.npz"
        if entry.get("status") == "done" and src.is_file():
            with atomic_path(out / "sequences" / f"{job.name}.npz") as tmp:
                try:
                    os.link(src, tmp)
                except OSError:
                    shutil.copyfile(src, tmp)
        elif entry.get("status") != "flagged":
            continue  # neither finished nor flagged there: simulate it here
        # a flagged clip is taken as flagged: the simulation is deterministic
        # an ensemble's member taken into a data set of none, or a clip into an ensemble
        manifest["sequences"][job.name] = {
            **{k: v for k, v in entry.items() if k not in MEMBER_KEYS},
            **member_fields(job),
            "reused_from": str(source),
            "device": entry.get("device", their_device),
            "cloth_fingerprint": cloth_fingerprint(ours["cloth"]),  # theirs, as compared above
        }
        write_json_atomic(out / "manifest.json", manifest)
        taken.append(job.name)
    return taken


def _recheck(
    jobs: list[Job], manifest: dict, out: Path, stale, still_right, keep
) -> tuple[list[str], list[str]]:
    """Clips recorded under another setting, kept or removed to be simulated again.

    Args:
        stale: ``stale(entry)``: whether the clip's entry was made under another setting.
        still_right: ``still_right(job, entry)``: whether this configuration makes the same
            clip (then it is kept).
        keep: ``keep(entry)`` updates a kept clip's entry to this configuration.

    Returns:
        The names of the clips kept and of those removed (their entry and sequence file).
    """
    kept, again = [], []
    for job in jobs:
        entry = manifest["sequences"].get(job.name)
        if entry is None or not stale(entry):
            continue
        if still_right(job, entry):
            keep(entry)
            kept.append(job.name)
        else:
            del manifest["sequences"][job.name]
            (out / "sequences" / f"{job.name}.npz").unlink(missing_ok=True)
            again.append(job.name)
    return kept, again


def recheck_release(
    config: DatasetConfig, jobs: list[Job], manifest: dict, out: Path, avatar, template
) -> tuple[list[str], list[str]]:
    """Clips simulated with another release of trapped cloth, kept or to simulate again.

    A clip recorded under another ``cloth.release_depth`` is the clip this configuration
    makes when the release never acted on it, in either: its entry counts no released
    frames, and the new release finds no cloth that deep in any of its frames
    (:func:`~loosefit.sim.release.replay_release` on the collider the simulation met). Such a
    clip is kept (its entry updated); any other (a flagged one too) is removed, to be
    simulated again.

    Returns:
        The names of the clips kept and of those removed.
    """
    from loosefit.data.format import read_sequence
    from loosefit.sim.release import TrappedRelease, release_parts, replay_release
    from loosefit.sim.timeline import collider_meshes, collider_parts, timeline

    depth, cloth = config.cloth.release_depth, config.cloth
    fingerprint = cloth_fingerprint(normalized(asdict(cloth)))  # a kept clip's
    built: dict = {}  # the collider's parts and meshes, for the first clip to replay

    def still_right(job: Job, entry: dict) -> bool:
        path = out / "sequences" / f"{job.name}.npz"
        if entry.get("status") != "done" or entry.get("released_frames") or not path.exists():
            return False
        if depth is None:
            return True
        if not built:
            built.update(
                parts=collider_parts(avatar, cloth), meshes=collider_meshes(avatar, cloth)[2]
            )
        # the collider's parts are the ones the pose correction tests (the arms the cloth meets)
        motion = job_motion(config, job, avatar, parts=built["parts"])
        line = timeline(avatar, motion, cloth, built["parts"])
        garment = read_sequence(path, template).garment_vertices
        release = TrappedRelease(
            line.collider[0],
            built["meshes"],
            release_parts(built["parts"]),
            template.num_vertices,
            depth,
            cloth.body_contact_distance,
        )
        return replay_release(garment, line.collider[line.n_pre :], release, 1.0 / motion.fps) == 0

    return _recheck(
        jobs,
        manifest,
        out,
        stale=lambda entry: entry.get("release_depth", depth) != depth,
        still_right=still_right,
        keep=lambda entry: entry.update(
            release_depth=depth,
            released_frames=0,
            released_vertices=0,
            cloth_fingerprint=fingerprint,
        ),
    )


def recheck_unfold(
    config: DatasetConfig, jobs: list[Job], manifest: dict, out: Path, avatar
) -> tuple[list[str], list[str]]:
    """Clips simulated under another pose correction, kept or to simulate again.

    A clip whose entry notes another ``unfold_config`` (:func:`open_manifest`) is the clip
    this configuration makes when both corrections give it the same motion, frame for frame
    (:func:`~loosefit.motion.pose_correction.same_correction`: a cap raised for deep folds
    leaves a clip without them as it was). Such a clip is kept (a flagged one stays flagged:
    the simulation is deterministic); any other is removed, to be simulated again.

    Returns:
        The names of the clips kept and of those removed.
    """
    from loosefit.motion.pose_correction import same_correction

    known = {f.name for f in dataclasses.fields(UnfoldConfig)}
    built: dict = {}  # the body parts the correction tests, for the first clip to check

    def still_right(job: Job, entry: dict) -> bool:
        stored = UnfoldConfig(**{k: v for k, v in entry["unfold_config"].items() if k in known})
        motion = job_motion(config, job, avatar, unfold=False)
        if not built:
            built["parts"] = limb_parts(config, avatar)
        return same_correction(avatar, motion, built["parts"], stored, config.unfold)

    return _recheck(
        jobs,
        manifest,
        out,
        stale=lambda entry: "unfold_config" in entry,
        still_right=still_right,
        keep=lambda entry: entry.pop("unfold_config"),
    )


MEMBER_KEYS = ("member_seed", "member_of", "motion_seed")  # an ensemble member's entry's


def member_fields(job: Job) -> dict:
    """An ensemble member's own entries in its clip's manifest entry (none for a clip of no
    ensemble): ``member_seed`` (its seed in ``DatasetConfig.seeds``), ``member_of`` (the
    clip's name) and ``motion_seed`` (the clip's seed, its motion's; the entry's ``seed``
    is the cloth's jitter's)."""
    if job.member_seed is None:
        return {}
    return {
        "member_seed": job.member_seed,
        "member_of": split_member(job.name)[0],
        "motion_seed": job.seed,
    }


def clip_entry(
    config: DatasetConfig, job: Job, motion, result, seconds: float = 0.0, failure: str = ""
) -> dict:
    """A clip's manifest entry: its result's quality, judged by ``config.limits``
    (``result`` None: the simulation failed with ``failure`` after ``seconds``). Its
    ``seed`` seeded the cloth's jitter (and the motion, but for an ensemble's member:
    :func:`member_fields`)."""
    entry = {
        "spec": short_spec(job.spec),
        "seed": job.jitter_seed,
        **member_fields(job),
        "frames": motion.num_frames,
        "test": job.test,
        # where it was simulated (a data set may be begun on a GPU and finished on the CPU),
        # and under which cloth configuration (DatasetReader.check_uniform)
        "device": config.cloth.device,
        "cloth_fingerprint": cloth_fingerprint(normalized(asdict(config.cloth))),
    }
    if result is None:
        entry.update(status="flagged", reason=failure, seconds=seconds)
        return entry
    qual = {k: v for k, v in result.quality.items() if np.isscalar(v)}
    lim = config.limits
    problems = []
    if qual.get("nan_count", 0) > 0:
        problems.append(f"{qual['nan_count']} NaN")
    if qual.get("penetration_max", 0.0) > lim.max_penetration_fraction:
        problems.append(
            f"inside the body: {qual['penetration_max']:.3f} of vertices deeper than "
            f"{PENETRATION_TOLERANCE * 1000:.0f} mm in a frame"
        )
    if qual.get("inside_depth_max", 0.0) > lim.max_inside_depth:
        problems.append(f"a vertex {qual['inside_depth_max'] * 100:.1f} cm inside the body")
    if qual.get("strain_p99", 0.0) > lim.max_strain_p99:
        problems.append(f"edge strain p99 {qual['strain_p99']:.3f}")
    if qual.get("max_speed", 0.0) > lim.max_speed:
        problems.append(f"vertex speed {qual['max_speed']:.1f} m/s")
    entry.update(
        status="flagged" if problems else "done",
        reason="; ".join(problems),
        # Simulation time summed over the runs a killed job was resumed in, plus this build
        # (a batch's shared evenly among its clips).
        seconds=result.stats["simulate_seconds"] + result.stats["build_seconds"],
        seconds_per_frame=result.seconds_per_frame,
        substeps_mean=result.stats["substeps_mean"],
        substeps_max=result.stats["substeps_max"],
        batch=result.stats["batch"],
        # the timeline frame a killed run was resumed from (absent: simulated in one go)
        **({"resumed_frame": first} if (first := result.stats.get("resumed_frame")) else {}),
        overlap_frames=result.stats["overlap_frames"],
        overlap_depth_max=result.stats["overlap_depth_max"],
        release_depth=config.cloth.release_depth,
        released_frames=result.stats["released_frames"],
        released_vertices=result.stats["released_vertices"],
        **motion.meta.get("unfold", {}),
        quality=qual,
    )
    return entry
