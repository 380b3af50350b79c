"""Which clips of a data set a model can be judged on (loosefit.eval.heldout)."""

from __future__ import annotations

from pathlib import Path

from loosefit.eval.heldout import EXPLODED_STRAIN_P99, validation_clips


class Reader:
    """What :func:`validation_clips` reads of a data set: its split, manifest and files."""

    def __init__(self, root: Path, sequences: dict, split: list[str], written: list[str]):
        self.root = root
        self.manifest = {"sequences": sequences}
        self._split = split
        for name in written:
            self.sequence_path(name).parent.mkdir(parents=True, exist_ok=True)
            self.sequence_path(name).write_bytes(b"")

    def split(self, which: str) -> list[str]:
        assert which == "all"
        return self._split

    def sequence_path(self, name: str) -> Path:
        return self.root / "sequences" / f"{name}.npz"


def test_the_clips_no_split_holds_and_that_did_not_tear(tmp_path, capsys):
    quality = lambda p99: {"quality": {"strain_p99": p99}}  # noqa: E731
    sequences = {
        "b_trained": quality(0.1),
        "a_spare": quality(0.2),
        "c_torn": quality(EXPLODED_STRAIN_P99 + 0.5),
        "d_unwritten": quality(0.1),
        "e_no_quality": {},
        "f_edge": quality(EXPLODED_STRAIN_P99),
    }
    written = ["b_trained", "a_spare", "c_torn", "e_no_quality", "f_edge"]
    reader = Reader(tmp_path, sequences, ["b_trained"], written)
    expect = [
        name
        for name in sorted(sequences)
        if name != "b_trained"
        and name in written
        and sequences[name].get("quality", {}).get("strain_p99", 0.0) <= EXPLODED_STRAIN_P99
    ]
    assert validation_clips(reader) == expect == ["a_spare", "e_no_quality", "f_edge"]
    assert "c_torn: left out" in capsys.readouterr().out
