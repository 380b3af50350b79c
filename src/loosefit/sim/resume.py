"""Resume files: a killed simulation's state, saved every few frames, and the key that
tells the same run from another."""

from __future__ import annotations

import hashlib
import math
import zipfile
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from loosefit.atomic import atomic_path
from loosefit.sim.cloth_config import ClothConfig
from loosefit.sim.release import TrappedRelease, replay_release
from loosefit.types import GarmentTemplate

# ClothConfig fields added after 2026-11-26, with the value that does what the solver did
# before they existed: at that value a field stays out of the run key, so that a run saved
# before it existed still resumes. Every new field goes here (why:
# docs/design/notes/cloth_config.md, "Resuming").
RUN_KEY_SINCE: dict[str, object] = {
    "self_contact_passes": 2,
    "settle_once": False,
    "initial_guess": "inertia",
    "chebyshev_rho": 0.0,
    "substep_body_move": None,
}


def run_key(body: np.ndarray, template: GarmentTemplate, config: ClothConfig) -> str:
    """A fingerprint of everything that decides a simulation's frames (but the device's
    rounding)."""
    h = hashlib.sha256()
    for a in (body[:: max(len(body) // 64, 1)], template.vertices, template.faces, template.waist):
        h.update(np.ascontiguousarray(a).tobytes())
    if template.rest_vertices is not None:  # a template without them keeps its key
        h.update(np.ascontiguousarray(template.rest_vertices).tobytes())
    # the release of trapped cloth does not enter it: a run it never changed is the same
    # (the resume checks that; see simulate_batch)
    # Nor does the device: a clip begun on a GPU goes on from its saved state on the CPU and
    # vice versa (the physics is the same; only the rounding differs). It is normalised to
    # "cpu" rather than dropped, so that a run saved on the CPU keeps the key it had.
    fields = asdict(replace(config, release_depth=None, device="cpu"))
    fields = {k: v for k, v in fields.items() if k not in RUN_KEY_SINCE or v != RUN_KEY_SINCE[k]}
    h.update(str((body.shape, sorted(fields.items()))).encode())
    return h.hexdigest()[:32]


def resumed_release(
    saved: dict,
    config: ClothConfig,
    colliders: list[np.ndarray],
    releases: list[TrappedRelease] | None,
    n_pre: int,
    frame_dt: float,
    *,
    released: list[np.ndarray],
) -> tuple[dict | None, list[np.ndarray]]:
    """A saved run's state for the release of trapped cloth, or None to start over.

    The run key leaves ``release_depth`` out, so a run saved with another release is found
    too: it is taken when the release never changed it, judged by the frames it recorded
    (:func:`replay_release`, which also gives the anchors) or the counts it saved.
    ``releases`` (one per clip, None when the release is off) take the saved run's anchors.

    Returns:
        ``saved`` (None: start over) and each clip's released counts per frame.
    """
    K = len(colliders)
    stored = float(saved.get("release_depth", np.nan))
    stored = None if math.isnan(stored) else stored
    counts = [np.asarray(saved.get(f"released_{c}", r)).copy() for c, r in enumerate(released)]
    if stored == config.release_depth:
        for c, release in enumerate(releases or []):
            if f"anchor_face_{c}" in saved:
                release.load({k: saved[f"{k}_{c}"] for k in release.state()})
        return saved, counts
    if any(r.any() for r in counts):
        return None, released  # the saved run's release moved cloth
    recorded = max(int(saved["frame"]) - n_pre + 1, 0)
    for c, release in enumerate(releases or []):
        g = saved[f"garment_{c}" if K > 1 else "garment"][:recorded]
        if replay_release(g, colliders[c][n_pre : n_pre + len(g)], release, frame_dt):
            return None, released
    return saved, counts


def write_resume(path: Path, **arrays) -> None:
    with atomic_path(path) as tmp:
        np.savez(tmp, **arrays)


def read_resume(path: Path, key: str, total: int) -> dict | None:
    """The saved state of the same run, or None (a missing, other or unreadable file)."""
    try:
        with np.load(path, allow_pickle=False) as data:
            if str(data["key"]) != key or not 0 < int(data["frame"]) <= total:
                return None
            return {k: data[k] for k in data.files}
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
        return None


def batch_key(
    bodies: list[np.ndarray],
    template: GarmentTemplate,
    config: ClothConfig,
    seeds: list[int] | None,
) -> str:
    """The run key of a batch of clips (each clip's :func:`run_key` with its seed; a lone
    clip's own)."""
    K = len(bodies)
    keys = [
        run_key(b, template, replace(config, seed=s))
        for b, s in zip(bodies, seeds or [config.seed] * K, strict=True)
    ]
    return keys[0] if K == 1 else hashlib.sha256("".join(keys).encode()).hexdigest()[:32]


@dataclass
class Recording:
    """What a batch run has recorded so far: what its resume file saves besides the
    simulator's state."""

    outs: list[np.ndarray]  # K (T, V, 3) each clip's motion frames, the first ones filled
    settled: np.ndarray  # (K, V, 3) the garments at the end of the settle phase
    released: list[np.ndarray]  # K (P + T,) cloth vertices put back on the skin per frame
    releases: list[TrappedRelease] | None  # each clip's release of trapped cloth, or None


def save_run(
    path: Path,
    key: str,
    frame: int,
    positions: np.ndarray,
    velocities: np.ndarray,
    rec: Recording,
    *,
    n_pre: int,
    release_depth: float | None,
    seconds: float,
) -> None:
    """Save a batch's state before timeline frame ``frame`` (atomically), for
    :func:`read_resume`.

    Args:
        path: the resume file.
        key: the run's :func:`batch_key`.
        frame: the timeline frame the run goes on from.
        positions, velocities: the simulator's state (:meth:`ClothSimulator.get_state`).
        rec: what the run has recorded.
        n_pre: frames before the motions' first.
        release_depth: the configuration's ``release_depth``.
        seconds: simulation seconds so far.
    """
    outs, settled, releases = rec.outs, rec.settled, rec.releases
    K = len(outs)
    recorded = max(frame - n_pre + 1, 0)
    garment = (
        {f"garment_{c}": out[: min(recorded, len(out))] for c, out in enumerate(outs)}
        if K > 1
        else {"garment": outs[0][:recorded]}
    )
    held = {  # the skin anchors of the release of trapped cloth, where it is on
        f"{k}_{c}": a for c, r in enumerate(releases or []) for k, a in r.state().items()
    }
    held.update({f"released_{c}": r for c, r in enumerate(rec.released)})
    held["release_depth"] = np.float64(np.nan if release_depth is None else release_depth)
    write_resume(
        path,
        key=np.array(key),
        frame=np.int64(frame),
        positions=positions,
        velocities=velocities,
        settled=settled if K > 1 else settled[0],
        seconds=np.float64(seconds),
        **garment,
        **held,
    )
