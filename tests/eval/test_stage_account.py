"""The stage account's measures of one garment against the simulation
(loosefit.eval.stage_account.measure), on a cylinder of cloth around a box."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from loosefit.eval.depth import inside_depths
from loosefit.eval.stage_account import STAGES, measure
from loosefit.model.losses import ClothStructure, dihedral_angles
from loosefit.types import GarmentTemplate
from tests.meshes import cube

RINGS, AROUND, T = 4, 12, 6


def tube(radius: float = 0.3) -> GarmentTemplate:
    """An open cylinder of cloth (RINGS rings of AROUND vertices, z from 0 down to -0.3 m),
    its top ring the waistband."""
    v = [
        (
            radius * math.cos(2 * math.pi * j / AROUND),
            radius * math.sin(2 * math.pi * j / AROUND),
            -0.1 * i,
        )
        for i in range(RINGS)
        for j in range(AROUND)
    ]
    f = []
    for i in range(RINGS - 1):
        for j in range(AROUND):
            a, b = i * AROUND + j, i * AROUND + (j + 1) % AROUND
            f += [[a, a + AROUND, b], [b, a + AROUND, b + AROUND]]
    v, f = np.asarray(v, np.float32), np.asarray(f, np.int64)
    return GarmentTemplate(v, f, 0.5 + v[:, :2], f, np.arange(AROUND))


@pytest.fixture(scope="module")
def clip():
    template = tube()
    structure = ClothStructure.from_template(template)
    hem = np.arange((RINGS - 1) * AROUND, RINGS * AROUND)
    shift = np.zeros((T, 1, 3), np.float32)
    shift[:, 0, 0] = 0.02 * np.arange(T)  # the dancer walks along x
    truth = template.vertices[None] + shift  # (T, V, 3)
    pelvis = shift[:, 0].astype(np.float64)
    box, box_faces = cube(0.4)
    body = box[None] + shift  # (T, 8, 3) the body under the skirt, moving with it
    angles = np.abs(
        dihedral_angles(torch.from_numpy(truth[::5]).double(), structure.hinges).numpy()
    ).ravel()
    return template, structure, hem, truth, pelvis, body, {"whole": box_faces}, angles


def figures(clip, x, window=(1, 5)):
    template, structure, hem, truth, pelvis, body, faces, angles = clip
    return measure(
        x,
        truth,
        structure,
        hem,
        pelvis,
        window,
        body=body,
        faces=faces,
        truth_angles=angles,
        fps=30.0,
        template=template,
    )


def test_the_simulation_against_itself(clip):
    truth = clip[3]
    out = figures(clip, truth)
    assert out["rmse_cm"] == 0 and out["hausdorff_cm"] == 0 and out["sted"] == 0
    assert out["strain_p50"] == pytest.approx(0, abs=1e-6)
    assert out["dihedral_w1"] == 0
    assert out["flare_mean_m"] == pytest.approx(0.3, abs=1e-6)
    assert out["flare_turn_error"] == pytest.approx(0, abs=1e-9)
    assert out["flare_turn_ratio"] == pytest.approx(1, abs=1e-9)
    assert len(out["flare_turn"]) == 4
    assert out["inside_whole_mean"] == 0 and out["deep_whole_frames"] == 0


def test_a_wider_hem_and_cloth_inside_the_body(clip):
    truth, pelvis, body, faces = clip[3], clip[4], clip[5], clip[6]
    x = truth.copy()
    hem = clip[2]
    x[:, hem, :2] = pelvis[:, None, :2] + 1.1 * (truth[:, hem, :2] - pelvis[:, None, :2])
    x[2:4, 0] = pelvis[2:4] + [0.0, 0.0, 0.15]  # a waist vertex 5 cm deep, two frames
    out = figures(clip, x)
    flare, flare_truth = [], []
    for t in range(1, 5):  # a plain loop over the window's frames
        flare.append(np.mean([math.dist(x[t, h, :2], pelvis[t, :2]) for h in hem]))
        flare_truth.append(np.mean([math.dist(truth[t, h, :2], pelvis[t, :2]) for h in hem]))
    ratio = np.asarray(flare) / np.asarray(flare_truth)
    np.testing.assert_allclose(out["flare_turn"], flare)
    assert out["flare_turn_ratio"] == pytest.approx(ratio.mean()) == pytest.approx(1.1)
    assert out["flare_turn_error"] == pytest.approx(np.abs(ratio - 1).mean())
    share, deep = inside_depths(x, body, faces["whole"])
    assert out["inside_whole_mean"] == share.mean() == pytest.approx(2 / (T * len(x[0])))
    assert out["deep_whole_frames"] == 2
    assert out["deepest_whole_m"] == pytest.approx(0.05, abs=1e-6) == deep.max()
    squared = ((x - truth) ** 2).sum(-1)
    assert out["rmse_cm"] == pytest.approx(100 * math.sqrt(squared.mean()), rel=1e-5)


def test_the_rows_are_the_pipeline_stage_by_stage():
    assert list(STAGES)[0] == "simulation" and list(STAGES)[-1] == "after"
    assert STAGES["simulation"] is None and STAGES["after"] is not None
