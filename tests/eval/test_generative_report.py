"""The generative ablation's table (loosefit.eval.generative_report)."""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.eval.generative_report import DECODERS, format_table, spread


def run(seed: int, rmse: float, hausdorff: float, sted: float) -> dict:
    return {
        "seed": seed,
        "epochs": 40,
        "machine": "dev-cpu",
        "parameters": 123456,
        "seconds_per_epoch": 2.5,
        "test": {"rmse_cm": rmse, "hausdorff_cm": hausdorff, "sted": sted},
        "train": {"rmse_cm": rmse / 2},
    }


def test_spread_is_the_mean_and_half_the_range():
    s = spread([1.0, 4.0, 2.0])
    assert s["mean"] == pytest.approx(7 / 3)
    assert s["half_range"] == 1.5
    assert s["values"] == [1.0, 4.0, 2.0]


def test_one_row_per_run_then_the_spread_per_decoder():
    rows = {
        "decomposed": [run(0, 1.0, 2.0, 0.1), run(1, 1.5, 2.5, 0.2)],
        "vertex": [run(0, 3.0, 4.0, 0.3)],
    }
    text = format_table(rows, "datasets/salsa", "cpu")
    lines = text.splitlines()
    assert lines[0].startswith("Held-out clips of `datasets/salsa`, preset `cpu`, 40 epochs")
    runs = [line for line in lines if line.startswith(f"| {DECODERS['decomposed']} | ")]
    assert runs[:2] == [
        f"| {DECODERS['decomposed']} | 0 | 1.000 | 2.000 | 0.1000 | 0.500 | 123,456 | 2.50 |",
        f"| {DECODERS['decomposed']} | 1 | 1.500 | 2.500 | 0.2000 | 0.750 | 123,456 | 2.50 |",
    ]
    h, st = np.mean([2.0, 2.5]), np.mean([0.1, 0.2])
    assert runs[2] == f"| {DECODERS['decomposed']} | 2 | 1.250 +- 0.250 | {h:.3f} | {st:.4f} |"
    assert f"| {DECODERS['vertex']} | 1 | 3.000 +- 0.000 | 4.000 | 0.3000 |" in lines
    assert lines[-1] == "Machine: dev-cpu."


def test_one_seed_each_gives_no_spread_table():
    text = format_table({"ssdr": [run(0, 1.0, 2.0, 0.1)]}, "d", "p")
    assert "mean +- half range" not in text
