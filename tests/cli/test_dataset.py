"""``loosefit dataset pack`` / ``unpack``: a data set made small to share and made again."""

from __future__ import annotations

import numpy as np

from loosefit.cli import build_parser, main


def test_the_pack_s_arguments():
    args = build_parser().parse_args(["dataset", "pack", "ds", "ds.pack"])
    assert (args.folder, args.out, args.workers) == ("ds", "ds.pack", 1)
    args = build_parser().parse_args(["dataset", "unpack", "ds.pack", "again"])
    assert (args.pack, args.dest) == ("ds.pack", "again")


def test_pack_then_unpack_gives_the_data_set_again(toy_dataset, tmp_path, capsys):
    from loosefit.data.format import DatasetReader

    pack = tmp_path / "toy.pack"
    assert main(["dataset", "pack", str(toy_dataset), str(pack)]) == 0
    assert pack.is_file()
    assert main(["dataset", "unpack", str(pack), str(tmp_path / "again")]) == 0
    before, after = DatasetReader(toy_dataset), DatasetReader(tmp_path / "again")
    assert before.split("all") == after.split("all")
    for name in before.split("all"):
        a, b = before.read(name), after.read(name)
        assert a.num_frames == b.num_frames
        # the pack codes the garments to a tolerance: within a millimetre
        assert np.abs(a.garment_vertices - b.garment_vertices).max() < 1e-3
