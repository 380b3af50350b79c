"""docs/results/PITCH_RESPONSE.md: does a motion stage move the skirt with the pelvis's pitch
as the simulation does?

The `dance-pitch` data set simulates clips again with the pelvis pitched (`NAME_pitchD`:
``pitch:D:NAME``, :func:`loosefit.motion.pelvis.pitch_pelvis`; the spine and legs as
captured). For each such clip and its unpitched original, and for the simulation and each
motion stage given (``--sets NAME=MOTION.pt``, rolled out alone, deterministic): over the
clip, the hem's mean tilt (the hem's mean height in front of the pelvis minus behind it,
in the heading frame: positive when the front of the hem rides higher) and its mean flare
(the hem ring's mean distance from the pelvis's vertical axis). The response is the pitched
clip's value minus the original's; a stage that reads the pitch as the cloth does responds
as the simulation does::

    OMP_NUM_THREADS=1 python bench/quality/pitch_response.py --data datasets/dance-pitch \\
        --sets shipped=checkpoints/dance/motion.pt --out docs/results/PITCH_RESPONSE.md

A stage trained on `dance-pitch` has trained on these clips: its row shows what it fits;
the shipped stage never saw a pitched clip.
"""

from __future__ import annotations

import argparse
import re
import time
from pathlib import Path

import numpy as np
import torch

import loosefit
from loosefit.data.format import DatasetReader
from loosefit.eval.hem import hem_flare, hem_tilt
from loosefit.garment.mesh_checks import hem_loop
from loosefit.inference.stages import MOTION_ONLY
from loosefit.motion.pelvis import pelvis_pitch
from loosefit.train.common import machine

PITCHED = re.compile(r"(.+)_pitch(-?[0-9.]+)")


def clip_figures(garment: np.ndarray, motion, hem: np.ndarray) -> tuple[float, float]:
    """(tilt, flare) in cm: the clip's mean hem tilt and hem flare
    (:func:`~loosefit.eval.hem.hem_tilt`, :func:`~loosefit.eval.hem.hem_flare`)."""
    T = min(len(garment), motion.num_frames)
    pelvis = np.asarray(motion.root_translation)[:T]
    forward = -np.asarray(motion.rotations[:T, 0, :, 1])  # the pelvis's -Y
    tilt = hem_tilt(garment[:T], pelvis, forward, hem).mean()
    flare = hem_flare(garment[:T], pelvis, hem).mean()
    return 100 * float(tilt), 100 * float(flare)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--data", default="datasets/dance-pitch")
    p.add_argument(
        "--sets", nargs="+", default=["shipped=checkpoints/dance/motion.pt"], help="NAME=MOTION.pt"
    )
    p.add_argument("--out", default="docs/results/PITCH_RESPONSE.md")
    p.add_argument("--threads", type=int, default=1)
    args = p.parse_args()
    torch.set_num_threads(args.threads)
    t0, started = time.perf_counter(), time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    reader = DatasetReader(args.data)
    names = set(reader.split("train"))
    pairs = sorted(
        (m.group(1), float(m.group(2)), n)
        for n in names
        if (m := PITCHED.fullmatch(n)) and m.group(1) in names
    )
    if not pairs:
        raise SystemExit(f"{args.data}: no NAME_pitchD training clip beside its NAME")
    sets = dict(s.split("=", 1) for s in args.sets)
    models = {name: loosefit.load(path).model for name, path in sets.items()}
    figures: dict[str, dict[str, tuple[float, float]]] = {}  # clip -> who -> (tilt, flare)
    pitches: dict[str, float] = {}  # clip -> the pelvis's median pitch, degrees

    def measure(clip: str) -> dict[str, tuple[float, float]]:
        if clip not in figures:
            seq = reader.read(clip)
            hem = hem_loop(seq.template.vertices, seq.template.faces)
            truth = np.asarray(seq.garment_vertices, np.float32)
            out = {"simulation": clip_figures(truth, seq.motion, hem)}
            for name, model in models.items():
                g = np.asarray(model.animate(seq.motion, stages=MOTION_ONLY).vertices)
                out[name] = clip_figures(g, seq.motion, hem)
            pitches[clip] = float(np.median(pelvis_pitch(seq.motion.rotations)))
            figures[clip] = out
            print(f"{clip}: done", flush=True)
        return figures[clip]

    who = ["simulation", *sets]
    lines = [
        "# The skirt's response to the pelvis's pitch",
        "",
        f"Made by `python bench/quality/pitch_response.py` on `{args.data}` with "
        + ", ".join(f"{n} = `{p}`" for n, p in sets.items())
        + f"; run {started} on {machine('cpu')}.",
        "",
        "Each clip simulated with the pelvis pitched D degrees (positive raises its front; the "
        "spine and legs as captured) against the same clip as captured. Over the clip: the "
        "hem's tilt (its mean height in front of the pelvis minus behind it, along the heading; "
        "cm) and its flare (the hem ring's mean distance from the pelvis's vertical axis; cm); "
        "each cell the pitched clip's value minus the original's. The motion stages alone, "
        "deterministic.",
        "",
        "| clip | pitch deg (captured, median) | D | "
        + " | ".join(f"{w}: tilt | {w}: flare" for w in who)
        + " |",
        "|---|---:|---:|" + "---:|---:|" * len(who),
    ]
    responses: dict[str, list[tuple[float, float]]] = {w: [] for w in who}
    for base, deg, pitched in pairs:
        a, b = measure(base), measure(pitched)
        cells = []
        for w in who:
            d = (b[w][0] - a[w][0], b[w][1] - a[w][1])
            responses[w].append(d)
            cells.append(f"{d[0]:+.1f} | {d[1]:+.1f}")
        lines.append(f"| {base} | {pitches[base]:+.1f} | {deg:+g} | " + " | ".join(cells) + " |")
    lines.append("")
    sim = np.array(responses["simulation"])
    for w in sets:
        r = np.array(responses[w])
        # least-squares gain of the stage's response on the simulation's, through zero
        gain = [
            float((r[:, k] * sim[:, k]).sum() / max((sim[:, k] ** 2).sum(), 1e-12)) for k in (0, 1)
        ]
        err = np.sqrt(((r - sim) ** 2).mean(0))
        lines.append(
            f"- {w}: its tilt response {gain[0]:.2f}x the simulation's (RMS difference "
            f"{err[0]:.1f} cm), its flare response {gain[1]:.2f}x ({err[1]:.1f} cm)."
        )
    lines.append(
        f"- The simulation's tilt response: {sim[:, 0].min():+.1f} to {sim[:, 0].max():+.1f} cm."
    )
    lines.append("")
    lines.append(f"{time.perf_counter() - t0:.0f} s.")
    Path(args.out).write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out} in {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
