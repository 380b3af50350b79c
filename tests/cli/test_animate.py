"""``loosefit animate --threads``: parsed, checked before the work, and what torch runs with."""

from __future__ import annotations

import pytest
import torch

from loosefit.cli import main


def test_threads_reach_torch_during_the_rollout_and_are_restored(tmp_path, monkeypatch, capsys):
    from loosefit.inference.animator import AnimationModel

    seen = []
    animate = AnimationModel.animate

    def watched(self, *args, **kwargs):
        seen.append(torch.get_num_threads())
        return animate(self, *args, **kwargs)

    monkeypatch.setattr(AnimationModel, "animate", watched)
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        out = tmp_path / "k.npz"
        assert main(["animate", "kick", "--frames", "3", "--threads", "1", "--out", str(out)]) == 0
        assert seen == [1] and torch.get_num_threads() == 2  # scoped: torch's count is back
        assert "1 torch thread (as --threads asks)" in capsys.readouterr().err
    finally:
        torch.set_num_threads(before)


@pytest.mark.parametrize("bad", ["0", "-1", "two", "1.5"])
def test_bad_thread_counts_are_refused_before_the_work(bad, tmp_path, capsys):
    out = tmp_path / "k.npz"
    assert main(["animate", "kick", "--frames", "3", "--threads", bad, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"--threads: field 'threads': expected a whole number, at least 1, found '{bad}'" in err
    assert "animating" not in err and not out.exists()  # nothing ran
