"""``loosefit motion`` and ``loosefit inspect-motion``."""

from loosefit.cli import main
from tests.conftest import SALSA, needs_salsa


def test_bad_motion_name_is_a_clear_error(tmp_path, capsys, avatar):
    code = main(["motion", "moonwalk", "--out", str(tmp_path / "m.npz")])
    assert code == 2
    err = capsys.readouterr().err
    assert "moonwalk" in err and "expected" in err and "found" in err
    assert not (tmp_path / "m.npz").exists()


def test_bad_shape_argument_is_a_clear_error(tmp_path, capsys):
    code = main(["motion", "spin", "--out", str(tmp_path / "m.npz"), "--shape", "gender"])
    assert code == 2 and "NAME=VALUE" in capsys.readouterr().err


@needs_salsa
def test_motion_from_bvh(tmp_path, avatar):
    from loosefit.types import Motion

    out = tmp_path / "salsa.npz"
    assert main(["motion", str(SALSA / "61_01.bvh"), "--out", str(out), "--max-frames", "60"]) == 0
    m = Motion.load(out)
    assert m.num_frames == 60 and m.fps == 30.0 and m.joint_names == avatar.joint_names


def test_inspect_motion_prints_the_matches(tmp_path, capsys, avatar):
    import dataclasses

    from loosefit.motion.motions import load_motion
    from tests.motion.bvh_conventions import CONVENTIONS, write_convention_bvh

    motion = load_motion("spin", avatar).slice(0, 12)
    path = write_convention_bvh(
        tmp_path / "mixamo.bvh", CONVENTIONS["mixamo"], avatar.skeleton, motion, avatar.floor_height
    )
    assert main(["inspect-motion", str(path)]) == 0
    out = capsys.readouterr().out
    parts = (
        "frames: 12 at 30 fps",
        "units: cm (guessed",
        "dancer: 1.",
        "joints (27):",
        "joint map: auto-matched",
        "mixamorig:HeadTop_End",
        "source joints not used",
    )
    for part in parts:
        assert part in out, part
    rows = {line.split()[0]: line.split()[1:] for line in out.splitlines()[1:] if line.strip()}
    assert rows["LeftUpLeg"] == ["mixamorig:LeftUpLeg", "name"]
    assert rows["Spine1"] == ["mixamorig:Spine2", "name"]
    # --units and --scale as for every motion command
    assert main(["inspect-motion", str(path), "--units", "m"]) == 0
    assert "outside 1.2-2.2 m" in capsys.readouterr().out
    # A skeleton it cannot map: the joints, then the error.
    keep = {a: s for a, s in CONVENTIONS["mixamo"].joints.items() if "Right" not in a}
    half = dataclasses.replace(CONVENTIONS["mixamo"], joints=keep, extras=[])
    path = write_convention_bvh(
        tmp_path / "half.bvh", half, avatar.skeleton, motion, avatar.floor_height
    )
    assert main(["inspect-motion", str(path)]) == 2
    captured = capsys.readouterr()
    assert "mixamorig:LeftUpLeg" in captured.out and "RightUpLeg" in captured.err


def test_motion_takes_a_joint_map_file(tmp_path, capsys, avatar):
    import dataclasses

    from loosefit.motion.motions import load_motion
    from loosefit.types import Motion
    from tests.motion.bvh_conventions import NAMELESS, write_convention_bvh

    names = {a: f"Knochen{i}" for i, a in enumerate(NAMELESS.joints)}  # made-up names
    conv = dataclasses.replace(NAMELESS, joints=names, up="+z", forward="-y")
    motion = load_motion("kick", avatar).slice(0, 10)
    bvh = write_convention_bvh(
        tmp_path / "k.bvh", conv, avatar.skeleton, motion, avatar.floor_height
    )
    mapping = tmp_path / "k.yaml"
    mapping.write_text(
        "".join(f"{a}: {s}\n" for a, s in names.items()) + "source_up: +z\nsource_forward: -y\n"
    )
    out = tmp_path / "k.npz"
    assert main(["motion", str(bvh), "--out", str(out), "--joint-map", str(mapping)]) == 0
    assert Motion.load(out).num_frames == 10
    capsys.readouterr()
    assert main(["inspect-motion", str(bvh), "--joint-map", str(mapping)]) == 0
    rows = [line.split() for line in capsys.readouterr().out.splitlines()]
    assert ["LeftUpLeg", "Knochen2", "map", "file"] in rows
    # A typo in the file names the file and the key.
    mapping.write_text("Hips: Knochen0\nLeftUpleg: Knochen2\n")
    assert main(["motion", str(bvh), "--out", str(out), "--joint-map", str(mapping)]) == 2
    err = capsys.readouterr().err
    assert "k.yaml" in err and "LeftUpleg" in err and "did you mean LeftUpLeg" in err


def test_motion_commands_take_gltf_and_smpl_files(tmp_path, capsys, avatar):
    import numpy as np

    from loosefit.motion.bvh import read_bvh
    from loosefit.motion.motions import load_motion
    from loosefit.types import Motion
    from tests.motion.bvh_conventions import CONVENTIONS, write_convention_bvh
    from tests.motion.gltf_writer import write_gltf

    motion = load_motion("spin", avatar).slice(0, 12)
    bvh = write_convention_bvh(
        tmp_path / "m.bvh", CONVENTIONS["mixamo"], avatar.skeleton, motion, avatar.floor_height
    )
    glb = write_gltf(tmp_path / "m.glb", read_bvh(bvh), idle_first=True)
    out = tmp_path / "m.npz"
    assert main(["motion", str(glb), "--out", str(out), "--animation", "dance"]) == 0
    assert Motion.load(out).num_frames == 12
    assert main(["inspect-motion", str(glb), "--animation", "1"]) == 0
    assert "animation: 'dance' (2 of 2" in capsys.readouterr().out
    assert main(["inspect-motion", str(glb), "--animation", "walk"]) == 2
    assert "'walk'" in capsys.readouterr().err
    smpl = tmp_path / "s.npz"
    np.savez(smpl, poses=np.zeros((8, 156)), trans=np.zeros((8, 3)), mocap_framerate=60.0)
    assert main(["motion", str(smpl), "--out", str(out), "--smpl-up", "+y"]) == 0
    assert Motion.load(out).num_frames == 4  # 60 fps resampled to 30
    assert main(["inspect-motion", str(smpl)]) == 0
    assert "up: +y in the file's world (detected" in capsys.readouterr().out


def test_inspect_motion_draws_the_capture_beside_the_avatar(tmp_path, capsys, avatar):
    import numpy as np
    from PIL import Image

    from loosefit.motion.joint_maps import load_joint_map_file
    from loosefit.motion.motions import load_motion
    from loosefit.render.renderer import Renderer
    from tests.motion.bvh_conventions import STUDIO_X, write_convention_bvh

    motion = load_motion("spin", avatar).slice(0, 20)
    path = write_convention_bvh(
        tmp_path / "studio.bvh", STUDIO_X, avatar.skeleton, motion, avatar.floor_height
    )
    mapping = tmp_path / "studio.yaml"
    args = ["inspect-motion", str(path), "--write-joint-map", str(mapping)]
    try:
        Renderer().close()
        sheet = tmp_path / "sheet.png"
        args += ["--sheet", str(sheet), "--sheet-frames", "4"]
    except RuntimeError:  # no headless OpenGL here: the report and the map only
        sheet = None
    assert main(args) == 0
    captured = capsys.readouterr()
    assert "calibration: clip" in captured.out and "studio.yaml" in captured.err
    assert load_joint_map_file(mapping).joints["LeftUpLeg"] == "UpperLeg_L"
    if sheet is not None:
        assert "pose check: passes" in captured.out
        image = np.asarray(Image.open(sheet))
        assert image.shape[0] > 300 and image.shape[1] > 1000  # 4 pictures, 3 to a row
        assert "frames [0, 6, 13, 19]" in captured.err
