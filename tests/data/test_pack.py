"""`loosefit dataset pack` / `unpack`: the round trip, and every way a pack can be broken."""

from __future__ import annotations

import hashlib
import importlib.util
import io
import json
import tarfile
from pathlib import Path

import numpy as np
import pytest

from loosefit.cli import main
from loosefit.data.clip_codec import STEP, decode_clip, decode_vertices, encode_vertices
from loosefit.data.format import FORMAT, DatasetReader, write_json_atomic, write_sequence
from loosefit.data.pack import INDEX, PACK_FORMAT, pack, unpack
from loosefit.data.pieces import PieceReader, find_pieces
from loosefit.errors import LoosefitInputError
from loosefit.sequence import GarmentSequence
from loosefit.types import GarmentTemplate, Motion
from tests.data.conftest import DANCE_PACK, LFZ, needs_corpus

V = 40
CLIPS = {"walk": 30, "jump": 3, "still": 1, "two": 2, "wild": 12}  # name: frames


def _template() -> GarmentTemplate:
    rng = np.random.default_rng(0)
    v = rng.uniform(-0.4, 0.4, size=(V, 3)) + [0.0, 0.0, 1.0]
    f = np.stack([np.arange(V - 2), np.arange(1, V - 1), np.arange(2, V)], 1)
    return GarmentTemplate(v, f, rng.uniform(0.1, 0.9, size=(V, 2)), f, np.arange(4), name="t")


def _clip(name: str, T: int, seed: int) -> GarmentSequence:
    rng = np.random.default_rng(seed)
    rot = np.tile(np.eye(3, dtype=np.float32), (T, 3, 1, 1))
    root = rng.normal(size=(T, 3)).astype(np.float32)
    motion = Motion(("a", "b", "c"), rot, root, 30.0, name)
    walk = np.cumsum(rng.normal(scale=0.003, size=(T, V, 3)), axis=0)  # (T, V, 3) a cloth's pace
    if name == "wild":  # jumps of a metre a frame: second differences beyond int16
        walk += rng.uniform(-1.5, 1.5, size=(T, 1, 1))
    g = (_template().vertices[None] + walk).astype(np.float32)
    return GarmentSequence(motion, _template(), g, {"rig": "cmu_mb", "shape": {}}, "test")


@pytest.fixture
def dataset(tmp_path):
    """A finished data set of five clips (1 to 30 frames), with a resume folder and a
    half-written clip that packing leaves out."""
    root = tmp_path / "ds"
    (root / "sequences").mkdir(parents=True)
    _template().save(root / "template.npz")
    for k, (name, T) in enumerate(CLIPS.items()):
        write_sequence(root / "sequences" / f"{name}.npz", _clip(name, T, k))
    manifest = {
        "format": FORMAT,
        "complete": True,
        "body": {"model": "anny", "rig": "cmu_mb", "shape": {}, "floor_height": 0.9},
        "sequences": {n: {"frames": T, "status": "done", "quality": {}} for n, T in CLIPS.items()},
        "split": {"train": ["walk", "jump", "still", "two"], "test": ["wild"]},
    }
    write_json_atomic(root / "manifest.json", manifest)
    (root / "resume").mkdir()
    (root / "resume" / "walk.npz").write_bytes(b"a killed run's state")
    (root / "sequences" / ".walk.partial.npz").write_bytes(b"half a clip")
    return root


def _members(path) -> list[tarfile.TarInfo]:
    with tarfile.open(path) as tar:
        return tar.getmembers()


def _without_index(path, out) -> None:
    """The same pack as the shared corpus's packer writes it: no index."""
    with tarfile.open(path) as src, tarfile.open(out, "w") as dst:
        for m in src.getmembers():
            if m.name != INDEX:
                dst.addfile(m, src.extractfile(m))


def _no_leftovers(folder) -> bool:
    return not [p for p in folder.iterdir() if ".partial" in p.name]


def test_round_trip(dataset, tmp_path):
    out = tmp_path / "ds.lfz"
    report = pack(dataset, out)
    assert report.paths == [out] and report.packed_bytes == out.stat().st_size
    assert report.files == 7 and report.clips == 5  # no resume/, no .partial
    assert report.max_error <= STEP / 2 + 2.0**-22  # float32's rounding (< 0.25 um) on top
    names = [m.name for m in _members(out)]
    assert names[0] == INDEX and "sequences/walk.npz.lfv" in names
    assert not any("resume" in n or "partial" in n for n in names)
    with tarfile.open(out) as tar:
        index = json.loads(tar.extractfile(INDEX).read())
        assert index["format"] == PACK_FORMAT and index["step"] == STEP
        assert [m["name"] for m in index["members"]] == names[1:]
        for m in index["members"]:
            data = tar.extractfile(m["name"]).read()
            assert m["size"] == len(data) and m["sha256"] == hashlib.sha256(data).hexdigest()

    report = unpack(out, tmp_path / "back")
    back = tmp_path / "back"
    assert report.indexed and report.clips == 5 and report.files == 7
    assert sorted(p.name for p in back.iterdir()) == ["manifest.json", "sequences", "template.npz"]
    assert (back / "manifest.json").read_bytes() == (dataset / "manifest.json").read_bytes()
    assert (back / "template.npz").read_bytes() == (dataset / "template.npz").read_bytes()
    for name in CLIPS:
        a = np.load(dataset / "sequences" / f"{name}.npz")
        b = np.load(back / "sequences" / f"{name}.npz")
        assert sorted(a.files) == sorted(b.files)  # garment_vertices comes last
        for k in a.files:
            assert a[k].dtype == b[k].dtype and a[k].shape == b[k].shape, k
            if k != "garment_vertices":
                assert np.array_equal(a[k], b[k]), k  # every other array exact
        err = np.abs(b["garment_vertices"].astype(np.float64) - a["garment_vertices"]).max()
        assert err <= STEP / 2 + 2.0**-22  # 0.01 mm, and float32's rounding near 2 m
    reader = DatasetReader(back)
    assert reader.read("walk").num_frames == 30 and reader.read("still").num_frames == 1
    assert _no_leftovers(tmp_path)


def test_the_codec_is_exact_on_quantised_positions_and_uses_int32_only_where_needed():
    rng = np.random.default_rng(3)
    q = np.cumsum(rng.integers(-50, 50, size=(9, 5, 3)), axis=0)  # (T, V, 3) steps
    g = (q * STEP).astype(np.float32)
    meta, blob = encode_vertices(g)
    assert meta["dd_dtype"] == "<i2"
    assert np.array_equal(decode_vertices(meta, blob), g)
    meta, _ = encode_vertices((g + (np.arange(9) % 2)[:, None, None]).astype(np.float32))
    assert meta["dd_dtype"] == "<i4"  # a metre back and forth each frame
    with pytest.raises(LoosefitInputError, match="float32"):
        encode_vertices(g.astype(np.float64))
    with pytest.raises(LoosefitInputError, match="finite"):
        encode_vertices(np.full((2, 5, 3), np.nan, np.float32))


def test_pieces_through_the_command_line(dataset, tmp_path, capsys):
    folder = tmp_path / "packs"
    folder.mkdir()
    out = folder / "ds.lfz"
    argv = ["dataset", "pack", str(dataset), str(out), "--piece-mib", "0.02", "--workers", "2"]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "x smaller than the .npz files" in printed and "within" in printed
    pieces = sorted(folder.iterdir())
    assert len(pieces) >= 3 and [p.name for p in pieces[:2]] == ["ds.lfz.000", "ds.lfz.001"]
    assert all(p.stat().st_size <= 0.02 * 2**20 for p in pieces)
    assert find_pieces(folder / "ds.lfz.") == pieces == find_pieces(folder)
    for source, dest in ((folder / "ds.lfz.", "a"), (folder, "b"), (folder / "ds.lfz", "c")):
        assert main(["dataset", "unpack", str(source), str(tmp_path / dest)]) == 0
        assert DatasetReader(tmp_path / dest).read("walk").num_frames == 30
    # packed again in fewer pieces: the earlier pack's last pieces go
    assert main(["dataset", "pack", str(dataset), str(out), "--piece-mib", "1"]) == 0
    assert sorted(p.name for p in folder.iterdir()) == ["ds.lfz.000"]
    # an error is one line naming where, and the command fails
    assert main(["dataset", "unpack", str(folder / "nothing."), str(tmp_path / "d")]) == 2
    assert "nothing" in capsys.readouterr().err


def _cuts(path) -> list[int]:
    """Where to cut a pack: at the start of every member's header (a boundary), inside
    a header, inside the data, and inside the last member's data."""
    cuts = {0, 100}
    for m in _members(path):
        cuts |= {m.offset, m.offset + 10, m.offset_data + 1, m.offset_data + m.size // 2}
    last = _members(path)[-1]
    return sorted(c for c in cuts if c < last.offset_data + last.size)


def _packed(dataset: Path, tmp_path: Path, indexed: bool) -> Path:
    """The data set packed with loosefit's index, or without it (as the shared corpus is)."""
    path = tmp_path / "ds.lfz"
    pack(dataset, path)
    if indexed:
        return path
    _without_index(path, tmp_path / "legacy.lfz")
    return tmp_path / "legacy.lfz"


@pytest.mark.parametrize("indexed", [True, False], ids=["index", "no-index"])
def test_a_truncated_pack_is_refused_and_leaves_nothing(dataset, tmp_path, indexed):
    whole = _packed(dataset, tmp_path, indexed)
    data = whole.read_bytes()
    cut = tmp_path / "cut.lfz"
    for n in _cuts(whole):
        cut.write_bytes(data[:n])
        with pytest.raises(LoosefitInputError, match=r"cut\.lfz: field '[^']+'") as err:
            unpack(cut, tmp_path / "dest")
        assert any(s in str(err.value) for s in ("truncated", "none readable", "ends inside"))
        assert not (tmp_path / "dest").exists() and _no_leftovers(tmp_path), n
    unpack(whole, tmp_path / "dest")  # the whole pack unpacks


def test_a_pack_without_index_is_checked_against_its_manifest(dataset, tmp_path):
    manifest = json.loads((dataset / "manifest.json").read_text())
    manifest["sequences"]["walk"]["frames"] = 31  # as if a frame was lost
    (dataset / "manifest.json").write_text(json.dumps(manifest))
    pack(dataset, tmp_path / "ds.lfz")
    _without_index(tmp_path / "ds.lfz", tmp_path / "legacy.lfz")
    with pytest.raises(LoosefitInputError, match=r"legacy\.lfz.*walk\.npz\.lfv.*31 frames"):
        unpack(tmp_path / "legacy.lfz", tmp_path / "dest")
    assert not (tmp_path / "dest").exists() and _no_leftovers(tmp_path)


@pytest.mark.parametrize("indexed", [True, False], ids=["index", "no-index"])
def test_a_corrupted_member_is_refused(dataset, tmp_path, indexed):
    path = _packed(dataset, tmp_path, indexed)
    m = next(m for m in _members(path) if m.name == "sequences/walk.npz.lfv")
    data = bytearray(path.read_bytes())
    data[m.offset_data + m.size - 20] ^= 0xFF  # in the compressed garment
    path.write_bytes(bytes(data))
    why = "corrupted" if indexed else "damaged"
    with pytest.raises(LoosefitInputError, match=rf"ds|legacy.*walk\.npz\.lfv.*{why}"):
        unpack(path, tmp_path / "dest")
    assert not (tmp_path / "dest").exists() and _no_leftovers(tmp_path)


def test_a_missing_piece_is_refused(dataset, tmp_path):
    out = tmp_path / "packs" / "ds.lfz"
    out.parent.mkdir()
    report = pack(dataset, out, piece_mib=0.02)
    assert len(report.paths) >= 3
    report.paths[1].rename(tmp_path / "elsewhere")
    with pytest.raises(LoosefitInputError, match=r"ds\.lfz\.001: field '<piece>'.*missing"):
        unpack(tmp_path / "packs" / "ds.lfz.", tmp_path / "dest")
    (tmp_path / "elsewhere").rename(report.paths[1])
    report.paths[-1].unlink()  # the last: nothing in the numbering says it is gone
    last = report.paths[-2].name
    with pytest.raises(LoosefitInputError, match=rf"{last}: field .*(missing|ends inside)"):
        unpack(tmp_path / "packs" / "ds.lfz.", tmp_path / "dest")
    assert not (tmp_path / "dest").exists() and _no_leftovers(tmp_path)


def test_a_destination_that_is_not_empty_is_refused(dataset, tmp_path):
    pack(dataset, tmp_path / "ds.lfz")
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "mine.txt").write_text("keep")
    with pytest.raises(LoosefitInputError, match="full.*new or empty folder.*remove it"):
        unpack(tmp_path / "ds.lfz", tmp_path / "full")
    assert [p.name for p in (tmp_path / "full").iterdir()] == ["mine.txt"]
    (tmp_path / "empty").mkdir()
    unpack(tmp_path / "ds.lfz", tmp_path / "empty")  # an empty folder is taken
    assert (tmp_path / "empty" / "manifest.json").is_file()


def test_pack_refuses_what_is_not_a_finished_data_set(dataset, tmp_path):
    with pytest.raises(LoosefitInputError, match="manifest"):
        pack(tmp_path, tmp_path.parent / "x.lfz")
    with pytest.raises(LoosefitInputError, match="piece_mib"):
        pack(dataset, tmp_path / "x.lfz", piece_mib=0)
    with pytest.raises(LoosefitInputError, match="outside the data set"):
        pack(dataset, dataset / "x.lfz")
    assert not (tmp_path / "x.lfz").exists()


# -- the shared corpus and its packer -------------------------------------------------------


def _lfz():
    spec = importlib.util.spec_from_file_location("lfz", LFZ)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@needs_corpus
def test_the_shared_corpus_unpacks_as_its_own_packer_unpacks_it(dance_unpacked, tmp_path):
    """One clip of the corpus, unpacked by lfz.py from its very bytes: the same arrays, bit
    for bit, as `loosefit dataset unpack` gave for the whole corpus."""
    member = "sequences/60_01.npz.lfv"
    reader = PieceReader(find_pieces(DANCE_PACK))
    with tarfile.open(fileobj=io.BufferedReader(reader), mode="r:") as tar:
        info = tar.getmember(member)
        data = tar.extractfile(info).read()
    one = tmp_path / "one.lfz"
    with tarfile.open(one, "w") as tar:
        info = tarfile.TarInfo(member)
        info.size = len(data)
        tar.addfile(info, io.BytesIO(data))
    _lfz().unpack(str(one), str(tmp_path / "lfz"))
    theirs = np.load(tmp_path / "lfz" / "sequences" / "60_01.npz")
    ours = np.load(dance_unpacked / "sequences" / "60_01.npz")
    assert list(theirs.files) == list(ours.files)
    for k in theirs.files:
        assert theirs[k].dtype == ours[k].dtype and theirs[k].tobytes() == ours[k].tobytes(), k
    assert np.array_equal(decode_clip(data)["garment_vertices"], ours["garment_vertices"])


@needs_corpus
def test_the_shared_packer_reads_our_packs(dataset, tmp_path):
    pack(dataset, tmp_path / "ds.lfz")
    _lfz().unpack(str(tmp_path / "ds.lfz"), str(tmp_path / "lfz"))
    unpack(tmp_path / "ds.lfz", tmp_path / "ours")
    for name in CLIPS:
        a = np.load(tmp_path / "lfz" / "sequences" / f"{name}.npz")
        b = np.load(tmp_path / "ours" / "sequences" / f"{name}.npz")
        assert all(np.array_equal(a[k], b[k]) for k in a.files)
