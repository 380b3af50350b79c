"""``loosefit demo`` (and ``render --sequence`` of what it wrote)."""

import imageio.v3 as iio
import pytest

from loosefit.cli import main


def test_demo_writes_video_and_sequence(tmp_path, capsys, avatar):
    out = tmp_path / "demo"
    args = ["demo", "--out", str(out), "--motion", "kick", "--no-physics", "--size", "96"]
    code = main([*args, "--views", "front"])
    assert code == 0
    assert (out / "sequence.npz").is_file() and (out / "video_sheet.png").is_file()
    frames = iio.imread(out / "video.mp4")
    assert frames.shape[0] > 30 and frames.shape[-1] == 3
    assert not list(out.glob("*partial*"))
    # The saved sequence renders again from the file.
    code = main(
        [
            "render",
            "--sequence",
            str(out / "sequence.npz"),
            "--out",
            str(out / "again"),
            "--size",
            "64",
            "--views",
            "side",
            "--start-frame",
            "20",
            "--max-frames",
            "5",
        ]
    )
    assert code == 0 and iio.imread(out / "again" / "video.mp4").shape[0] == 5
    # A start past the clip's end names the option and the range.
    code = main(
        [
            "render",
            "--sequence",
            str(out / "sequence.npz"),
            "--out",
            str(out / "late"),
            "--start-frame",
            "100000",
        ]
    )
    assert code == 2 and not (out / "late" / "video.mp4").exists()
    assert "--start-frame" in capsys.readouterr().err


def test_demo_animates_the_pretrained_model_and_exports_it(tmp_path, capsys):
    """The README's main job as it runs, on a short clip."""
    import numpy as np

    from loosefit.export import read_pc2
    from loosefit.export.meshes import in_up_axis
    from loosefit.sequence import GarmentSequence

    out = tmp_path / "demo"
    args = [
        "demo",
        "--out",
        str(out),
        "--motion",
        "kick",
        "--max-frames",
        "30",
        "--size",
        "64",
        "--views",
        "front",
    ]
    assert main(args) == 0
    seq = GarmentSequence.load(out / "sequence.npz")
    assert seq.source.startswith("loosefit model") and seq.garment_vertices.shape[0] == 30
    err = capsys.readouterr().err  # throughput apart from the clip's own rate
    assert "animated 30 frames of a 30 fps clip (1.0 s) in" in err and "frames per second" in err
    cache, _, _ = read_pc2(out / "demo.pc2")
    np.testing.assert_array_equal(cache, in_up_axis(seq.garment_vertices, "Y"))  # OBJ's axes
    for name in ("demo.usdc", "demo.obj", "demo_body.pc2", "video.mp4", "video_sheet.png"):
        assert (out / name).is_file(), name
    assert iio.imread(out / "video.mp4").shape[0] == 30
    # the pretrained model animates its own skirt: another garment is a clear error
    assert main([*args, "--garment", "circle"]) == 2


@pytest.mark.slow
def test_demo_with_physics(tmp_path, avatar):
    """The README's main job as it runs, on a short clip (minutes on a CPU)."""
    out = tmp_path / "demo"
    args = [
        "demo",
        "--out",
        str(out),
        "--max-frames",
        "10",
        "--size",
        "64",
        "--views",
        "front",
        "--physics",
    ]
    assert main(args) == 0
    from loosefit.sequence import GarmentSequence

    seq = GarmentSequence.load(out / "sequence.npz")
    assert seq.source == "newton-vbd" and seq.garment_vertices.shape[0] == 10


@pytest.mark.parametrize("mode", ["--no-physics", "--physics"])
def test_demo_threads_only_with_the_learned_model(tmp_path, capsys, mode):
    """--threads sets the learned model's threads: with the simulator or a rigid skirt it is
    refused, not ignored; a bad count is refused before the work."""
    assert main(["demo", "--out", str(tmp_path), mode, "--threads", "2"]) == 2
    assert "no --threads with --physics or --no-physics" in capsys.readouterr().err
    assert main(["demo", "--out", str(tmp_path), "--threads", "0"]) == 2
    assert "--threads: field 'threads'" in capsys.readouterr().err
    assert not (tmp_path / "sequence.npz").exists()
