"""Progress bars fed by (done, total) callbacks: the counts reach the bar, one bar a stage."""

from __future__ import annotations

import pytest

pytest.importorskip("tqdm", reason="tqdm draws the bars")

from loosefit.progress import StageBars, tqdm_bar  # noqa: E402


def test_a_bar_follows_done_and_a_total_that_changes(capsys):
    bar = tqdm_bar("simulate", "frame")
    bar.progress(3, 10)
    assert (bar.bar.n, bar.bar.total) == (3, 10)
    bar.progress(7, 12)  # the total can grow as work is found
    assert (bar.bar.n, bar.bar.total) == (7, 12)
    bar.close()
    assert "simulate" in capsys.readouterr().err


def test_one_bar_a_stage_each_with_its_unit(capsys):
    bars = StageBars("train", {"epochs": "epoch"})
    bars.progress("epochs", 1, 4)
    first = bars.bar
    assert (first.n, first.total, first.unit, bars.stage) == (1, 4, "epoch", "epochs")
    bars.progress("epochs", 3, 4)
    assert bars.bar is first and first.n == 3
    bars.progress("export", 0, 1)  # the next stage: a new bar, the unit by default
    assert bars.bar is not first and bars.bar.unit == "step" and bars.stage == "export"
    assert first.n == 3  # the first bar stays, with its count
    bars.close()
    assert (bars.stage, bars.bar) == (None, None)
    err = capsys.readouterr().err
    assert "train: epochs" in err and "train: export" in err
