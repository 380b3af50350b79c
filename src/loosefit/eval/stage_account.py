"""An account of every stage of the pipeline against the simulation, on one clip.

The rows (:data:`STAGES`):

* ``simulation``: the ground truth itself;
* ``oracle``: the generative model's own reconstruction of the truth (encode, decode);
* ``oracle + lengths``: that, with the edge-length stage;
* ``motion stage``: the rollout's decoded garment;
* ``+ detail``: with the detail stage (paper 3.4);
* ``today``: + collision handling without the arms in the collider and without the last
  projection (:data:`TODAY_COLLISION`);
* ``+ lengths``: + detail + the edge-length stage;
* ``+ lengths, all edges``: the same restoring every edge, not only the hanging ones;
* ``after``: the whole pipeline (detail, edge lengths, collision handling against the
  whole body with the last projection).

The measures of one garment (:func:`measure`): edge strain ``|l/L - 1|`` median and p99 and
the median signed edge change; the dihedral angles' mean and 1-Wasserstein distance from the
simulation's; hem flare over the clip and around its fastest turn; cloth inside the body
(:func:`~loosefit.eval.depth.inside_depths`), whole body and the simulation's collider;
RMSE, Hausdorff and STED against the simulation.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
import torch

from loosefit.eval.depth import inside_depths
from loosefit.eval.heading import fastest_turn
from loosefit.eval.hem import hem_flare
from loosefit.eval.metrics import hausdorff, rmse, sted
from loosefit.garment.mesh_checks import hem_loop
from loosefit.garment.quality import PENETRATION_TOLERANCE
from loosefit.inference.stages import MOTION_ONLY, Stages
from loosefit.inference.stages.collision import CollisionConfig
from loosefit.model.losses import ClothStructure, dihedral_angles, signed_edge_change

STAGES = {  # label: stages (None: not a rollout)
    "simulation": None,
    "oracle": None,
    "oracle + lengths": None,
    "motion stage": MOTION_ONLY,
    "+ detail": Stages(lengths=False, collision=False),
    "today": Stages(lengths=False),
    "+ lengths": Stages(collision=False),
    "+ lengths, all edges": Stages(collision=False),  # LengthConfig(edges="all")
    "after": Stages(),
}
TODAY_COLLISION = CollisionConfig(finish=0, whole_body=False)  # no arms, no last projection
TURN_WINDOW = 30  # frames either side of the fastest turn


def measure(
    x, truth, structure, hem, pelvis, window, *, body, faces, truth_angles, fps, template
) -> dict:
    """The figures of one stage's garment (T, V, 3) against the simulation."""
    xt = torch.from_numpy(np.ascontiguousarray(x))
    change = signed_edge_change(xt, structure.edges, structure.rest_lengths).numpy()
    sub = slice(None, None, 5)
    angles = np.abs(dihedral_angles(xt[sub].double(), structure.hinges).numpy()).ravel()
    q = np.linspace(0.005, 0.995, 199)
    fl, fl_truth = hem_flare(x, pelvis, hem), hem_flare(truth, pelvis, hem)
    w = slice(*window)
    out = {
        "strain_p50": float(np.median(np.abs(change))),
        "strain_p99": float(np.quantile(np.abs(change), 0.99)),
        "edge_change_p50": float(np.median(change)),
        "dihedral_mean": float(angles.mean()),
        "dihedral_w1": float(np.abs(np.quantile(angles, q) - np.quantile(truth_angles, q)).mean()),
        "flare_mean_m": float(fl.mean()),
        "flare_turn_error": float(np.mean(np.abs(fl[w] / fl_truth[w] - 1))),
        "flare_turn_ratio": float(np.mean(fl[w] / fl_truth[w])),
        "flare_turn": fl[w].tolist(),
    }
    for key, f in faces.items():
        share, deep = inside_depths(x, body, f)
        out[f"inside_{key}_mean"] = float(share.mean())
        out[f"inside_{key}_max"] = float(share.max())  # the worst frame's share
        out[f"deep_{key}_frames"] = int((deep > PENETRATION_TOLERANCE).sum())
        out[f"deepest_{key}_m"] = float(deep.max())
    out["rmse_cm"] = 100 * rmse(x, truth)
    out["hausdorff_cm"] = 100 * float(hausdorff(x, truth, template.faces).mean())
    out["sted"] = float(sted(x, truth, template.faces)["sted"])
    return out


def clip_reference(model, seq):
    """``(measure, turn, window)`` of one simulated clip: ``measure(x)`` gives the figures of
    a garment (T, V, 3) on its motion against the simulation (:func:`measure`); ``turn`` is
    the frame of the fastest turn and ``window`` the frames around it."""
    motion, truth = seq.motion, np.asarray(seq.garment_vertices, np.float32)
    template = model.template
    structure = ClothStructure.from_template(template)
    hem = hem_loop(template.vertices, template.faces)
    avatar = model.avatar()
    posed = avatar.pose_motion(motion)
    body = posed.vertices.cpu().numpy()
    pelvis = posed.joint_poses[:, 0, :3, 3].cpu().numpy()
    turn = fastest_turn(motion.rotations[:, 0], motion.fps, 5, "gradient")
    window = (max(turn - TURN_WINDOW, 0), min(turn + TURN_WINDOW + 1, motion.num_frames))
    faces = {
        "whole": avatar.collider_faces(arms=True).cpu().numpy(),
        "collider": avatar.collider_faces(arms=model.arm_collision).cpu().numpy(),
    }
    truth_angles = np.abs(
        dihedral_angles(torch.from_numpy(truth[::5]).double(), structure.hinges).numpy()
    ).ravel()

    def measure_garment(x: np.ndarray) -> dict:
        return measure(
            x,
            truth,
            structure,
            hem,
            pelvis,
            window,
            body=body,
            faces=faces,
            truth_angles=truth_angles,
            fps=motion.fps,
            template=template,
        )

    return measure_garment, turn, window


def clip_account(model, name: str, seq, labels=tuple(STAGES), before=None) -> dict:
    """Every stage of ``labels`` (keys of :data:`STAGES`) on one simulated clip; the
    ``today`` row with the pipeline ``before`` when given (e.g. the set before the physics
    terms)."""
    motion, truth = seq.motion, np.asarray(seq.garment_vertices, np.float32)
    measure_garment, turn, window = clip_reference(model, seq)
    restorer = model.restorer(Stages())
    rows, seconds, oracle = {}, {}, None
    for label in labels:
        stages = STAGES[label]
        t0 = time.perf_counter()
        if label == "simulation":
            x = truth
        elif label.startswith("oracle"):  # the reconstruction once, for both oracle rows
            if oracle is None:
                oracle = model.reconstruct(motion, truth).vertices
            x = restorer(torch.from_numpy(oracle)).numpy() if label.endswith("lengths") else oracle
        else:
            collision = TODAY_COLLISION if label == "today" else None
            lengths = replace(model.lengths, edges="all") if label.endswith("all edges") else None
            which = before if label == "today" and before is not None else model
            with which.configured(collision, lengths):
                x = which.animate(motion, stages=stages).vertices
        seconds[label] = time.perf_counter() - t0
        rows[label] = measure_garment(x)
        print(
            f"  {name} {label}: strain {rows[label]['strain_p50']:.3f}, edge change "
            f"{100 * rows[label]['edge_change_p50']:+.1f} %, flare error at the turn "
            f"{100 * rows[label]['flare_turn_error']:.1f} %, inside (whole body) "
            f"{100 * rows[label]['inside_whole_mean']:.3f} %, RMSE "
            f"{rows[label]['rmse_cm']:.2f} cm",
            flush=True,
        )
    return {
        "frames": motion.num_frames,
        "turn_frame": turn,
        "window": window,
        "rows": rows,
        "seconds": seconds,
    }
