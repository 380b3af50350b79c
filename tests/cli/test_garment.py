"""``loosefit garment``: a style or a garment file; ``--fit`` only for a file."""

from __future__ import annotations

from loosefit.cli import build_parser, main


def test_the_garment_s_arguments():
    args = build_parser().parse_args(["garment", "aline"])
    assert (args.source, args.out, args.resolution, args.length, args.fit) == (
        "aline",
        "out/garment",
        "cpu",
        None,
        False,
    )


def test_fit_of_a_style_is_refused_before_any_work(tmp_path, capsys):
    out = tmp_path / "g"
    assert main(["garment", "aline", "--fit", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--fit" in err and "a garment file (.obj, .gltf, .glb)" in err and "'aline'" in err
    assert not out.exists()
