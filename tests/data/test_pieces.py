import io

import pytest

from loosefit.data.pieces import PieceReader, PieceWriter, find_pieces
from loosefit.errors import LoosefitInputError

DATA = bytes(range(256)) * 3 + b"tail"  # 772 bytes


def _write(folder, limit):
    folder.mkdir(exist_ok=True)
    writer = PieceWriter(folder, limit)
    for start in range(0, len(DATA), 100):  # in writes that straddle the pieces
        assert writer.write(DATA[start : start + 100]) == len(DATA[start : start + 100])
    assert writer.tell() == len(DATA)
    writer.close()
    return writer.paths


def test_a_writer_cuts_pieces_of_the_limit_and_a_reader_joins_them(tmp_path):
    paths = _write(tmp_path / "pack", 300)
    assert [p.name for p in paths] == ["piece-000", "piece-001", "piece-002"]
    assert [p.stat().st_size for p in paths] == [300, 300, 172]
    assert b"".join(p.read_bytes() for p in paths) == DATA
    with PieceReader(paths) as reader:
        assert reader.size == len(DATA) and reader.read() == DATA


def test_no_limit_is_one_piece(tmp_path):
    paths = _write(tmp_path / "pack", None)
    assert len(paths) == 1 and paths[0].read_bytes() == DATA


def test_the_reader_seeks_across_pieces(tmp_path):
    paths = _write(tmp_path / "pack", 300)
    with PieceReader(paths) as raw:
        assert raw.seek(290) == 290
        assert raw.read(20) == DATA[290:300]  # a raw read stops at the piece's end
        assert raw.read(10) == DATA[300:310] and raw.tell() == 310
        assert raw.seek(-10, io.SEEK_END) == len(DATA) - 10 and raw.read() == DATA[-10:]
        assert raw.read(5) == b""  # at the end
        raw.seek(-700, io.SEEK_CUR)
        assert raw.read(3) == DATA[72:75]
        assert raw.seek(-5) == 0
        assert raw.piece_at(0) == paths[0] and raw.piece_at(299) == paths[0]
        assert raw.piece_at(300) == paths[1] and raw.piece_at(10**6) == paths[2]
    with io.BufferedReader(PieceReader(paths), buffer_size=64) as buffered:
        buffered.seek(250)
        assert buffered.read(400) == DATA[250:650]  # across three pieces


def test_pieces_are_found_by_file_folder_or_prefix(tmp_path):
    paths = _write(tmp_path / "pack", 300)
    assert find_pieces(tmp_path / "pack") == paths
    assert find_pieces(paths[1]) == [paths[1]]
    for k in range(11):
        (tmp_path / f"dance.lfz.{k:03d}").write_bytes(b"x")
    (tmp_path / "dance.lfz.txt").write_bytes(b"notes")
    found = find_pieces(tmp_path / "dance.lfz.")
    assert [p.name for p in found] == [f"dance.lfz.{k:03d}" for k in range(11)]
    assert find_pieces(tmp_path / "dance.lfz") == found  # the dot may be left out


def test_missing_pieces_and_mixed_packs_are_refused(tmp_path):
    with pytest.raises(LoosefitInputError, match="found nothing there"):
        find_pieces(tmp_path / "nothing.lfz.")
    folder = tmp_path / "pack"
    paths = _write(folder, 300)
    paths[1].unlink()
    with pytest.raises(LoosefitInputError) as err:
        find_pieces(folder)
    assert err.value.source == str(folder / "piece-001") and err.value.found == "missing"
    (folder / "piece-001").write_bytes(b"")
    (folder / "other.003").write_bytes(b"")
    with pytest.raises(LoosefitInputError, match="pieces named other., piece-"):
        find_pieces(folder)
