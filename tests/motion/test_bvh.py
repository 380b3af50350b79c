"""BVH reader: hand-computed forward kinematics, units, every bad-input error, real clips."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.motion.bvh import read_bvh
from loosefit.motion.skeleton_clip import end_site_positions, forward_kinematics, rest_positions

SHARED = Path(__file__).resolve().parents[3] / "shared"
SALSA = SHARED / "mocap" / "cmu-salsa"
needs_salsa = pytest.mark.skipif(
    not SALSA.exists(), reason="../shared (CMU salsa clips) not present beside the repository"
)


def chain_bvh(order: str, unit: float = 1.0, frame_time: str = "0.0333333") -> str:
    """A four-joint chain root -> j1 -> j2 -> j3, every joint rotating in ``order``.

    Frame 0 is the rest pose. Frame 1 moves the root to (1, 2, 3) and sets the
    rotation channels of j1 to (90, 90, 0) and of j2 to (0, 0, 90), in the order
    they are listed, so the answer depends on the order.
    """
    rot = " ".join(f"{axis}rotation" for axis in order)
    u = unit
    return f"""HIERARCHY
ROOT root
{{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition {rot}
  JOINT j1
  {{
    OFFSET 0 {u} 0
    CHANNELS 3 {rot}
    JOINT j2
    {{
      OFFSET {u} 0 0
      CHANNELS 3 {rot}
      JOINT j3
      {{
        OFFSET 0 0 {u}
        CHANNELS 3 {rot}
        End Site
        {{
          OFFSET 0 0 {0.5 * u}
        }}
      }}
    }}
  }}
}}
MOTION
Frames: 2
Frame Time: {frame_time}
0 0 0 0 0 0 0 0 0 0 0 0 0 0 0
{u} {2 * u} {3 * u} 0 0 0 90 90 0 0 0 90 0 0 0
"""


def write(tmp_path: Path, text: str, name: str = "clip.bvh") -> Path:
    path = tmp_path / name
    path.write_text(text, newline="")
    return path


# Worked by hand with Rx(90): (x, y, z) -> (x, -z, y), Ry(90): (x, y, z) -> (z, y, -x),
# Rz(90): (x, y, z) -> (-y, x, z). j1 sits at root + (0, 1, 0) = (1, 3, 3); then
# j2 = j1 + R1 e_x with R1 = R_a(90) R_b(90) for the first two letters (a, b), and
# j3 = j2 + R1 R_c(90) e_z with c the third letter.
#   ZXY: R1 e_x = Rz Rx e_x = Rz e_x = e_y;            R1 Ry e_z = R1 e_x = e_y
#   ZYX: R1 e_x = Rz Ry e_x = Rz (-e_z) = -e_z;         R1 Rx e_z = R1 (-e_y) = Rz(-e_y) = e_x
#   XYZ: R1 e_x = Rx Ry e_x = Rx (-e_z) = e_y;          R1 Rz e_z = Rx Ry e_z = Rx e_x = e_x
#   YXZ: R1 e_x = Ry Rx e_x = Ry e_x = -e_z;            R1 Rz e_z = Ry Rx e_z = Ry(-e_y) = -e_y
HAND_COMPUTED = {
    "ZXY": [[1, 2, 3], [1, 3, 3], [1, 4, 3], [1, 5, 3]],
    "ZYX": [[1, 2, 3], [1, 3, 3], [1, 3, 2], [2, 3, 2]],
    "XYZ": [[1, 2, 3], [1, 3, 3], [1, 4, 3], [2, 4, 3]],
    "YXZ": [[1, 2, 3], [1, 3, 3], [1, 3, 2], [1, 2, 2]],
}
REST = [[0, 0, 0], [0, 1, 0], [1, 1, 0], [1, 1, 1]]


@pytest.mark.parametrize("order", sorted(HAND_COMPUTED))
def test_forward_kinematics_hand_computed(tmp_path, order):
    clip = read_bvh(write(tmp_path, chain_bvh(order)))
    assert clip.joint_names == ("root", "j1", "j2", "j3")
    assert clip.parents.tolist() == [-1, 0, 1, 2]
    assert clip.channels[1] == tuple(f"{a}rotation" for a in order)
    assert clip.num_frames == 2
    pos, world = forward_kinematics(clip)
    assert pos.shape == (2, 4, 3) and world.shape == (2, 4, 3, 3)
    np.testing.assert_allclose(pos[0], REST, atol=1e-6)
    np.testing.assert_allclose(pos[1], HAND_COMPUTED[order], atol=1e-6)
    np.testing.assert_allclose(rest_positions(clip), REST, atol=1e-6)
    # The world rotation of j2 carries the j2 -> j3 offset: (j3 - j2) = G_j2 e_z.
    np.testing.assert_allclose(world[1, 2] @ [0, 0, 1], pos[1, 3] - pos[1, 2], atol=1e-6)
    np.testing.assert_allclose(clip.root_positions, [[0, 0, 0], [1, 2, 3]], atol=1e-6)


def test_end_sites(tmp_path):
    clip = read_bvh(write(tmp_path, chain_bvh("ZXY")))
    assert list(clip.end_offsets) == [3]
    np.testing.assert_allclose(clip.end_offsets[3], [0, 0, 0.5])
    ends = end_site_positions(clip)
    # ZXY frame 1: j3 at (1, 5, 3), the chain beyond j2 points along +Y.
    np.testing.assert_allclose(ends[3], [[1, 1, 1.5], [1, 5.5, 3]], atol=1e-6)


INTERLEAVED = """HIERARCHY
ROOT hip
{
  OFFSET 0 0 0
  CHANNELS 6 Yrotation Zposition Xposition Xrotation Yposition Zrotation
  JOINT arm
  {
    OFFSET 1 0 0
    CHANNELS 6 Zrotation Yposition Xrotation Xposition Yrotation Zposition
    JOINT hand
    {
      OFFSET 0 0 1
      CHANNELS 0
      End Site
      {
        OFFSET 0 0 1
      }
    }
  }
}
MOTION
Frames: 1
Frame Time: 0.01
90 3 1 0 2 0   0 0.5 0 0 0 0
"""


def test_interleaved_position_channels(tmp_path):
    path = write(tmp_path, INTERLEAVED)
    clip = read_bvh(path)
    assert clip.channels[2] == ()
    np.testing.assert_allclose(clip.root_positions, [[1, 2, 3]])
    # hip: at (1, 2, 3), turned Ry(90). arm: local (1, 0, 0) + (0, 0.5, 0), so
    # (1, 2, 3) + Ry(90) (1, 0.5, 0) = (1, 2, 3) + (0, 0.5, -1). hand: + Ry(90) e_z = + e_x.
    pos, _ = forward_kinematics(clip)
    np.testing.assert_allclose(pos[0], [[1, 2, 3], [1, 2.5, 2], [2, 2.5, 2]], atol=1e-6)
    np.testing.assert_allclose(clip.rotations[0, 2], np.eye(3))
    # "replace": the arm's position channels (0, 0.5, 0) replace its offset.
    pos, _ = forward_kinematics(read_bvh(path, position_channels="replace"))
    np.testing.assert_allclose(pos[0], [[1, 2, 3], [1, 2.5, 3], [2, 2.5, 3]], atol=1e-6)


def test_units(tmp_path):
    metres = read_bvh(write(tmp_path, chain_bvh("ZXY"), "m.bvh"))
    expected = forward_kinematics(metres)[0]
    assert metres.units_scale == 1.0
    cm_path = write(tmp_path, chain_bvh("ZXY", unit=100.0), "cm.bvh")
    mm_path = write(tmp_path, chain_bvh("ZXY", unit=1000.0), "mm.bvh")
    for clip in (read_bvh(cm_path), read_bvh(cm_path, units="cm"), read_bvh(mm_path)):
        np.testing.assert_allclose(forward_kinematics(clip)[0], expected, atol=1e-5)
        np.testing.assert_allclose(clip.offsets, metres.offsets, atol=1e-6)
        np.testing.assert_allclose(clip.end_offsets[3], metres.end_offsets[3], atol=1e-6)
    assert read_bvh(cm_path).units_scale == 0.01
    assert read_bvh(mm_path).units_scale == 0.001
    # An explicit scale overrides the guess.
    doubled = read_bvh(write(tmp_path, chain_bvh("ZXY"), "m.bvh"), scale=2.0)
    np.testing.assert_allclose(forward_kinematics(doubled)[0], 2 * expected, atol=1e-5)
    # units="m" on a cm file keeps the numbers as written.
    np.testing.assert_allclose(read_bvh(cm_path, units="m").offsets[1], [0, 100, 0])
    with pytest.raises(LoosefitInputError, match="units"):
        read_bvh(cm_path, units="furlong")
    with pytest.raises(LoosefitInputError, match="scale"):
        read_bvh(cm_path, scale=-1.0)


def test_frame_time_and_fps(tmp_path):
    clip = read_bvh(write(tmp_path, chain_bvh("ZXY", frame_time="0.008333")))
    assert clip.frame_time == pytest.approx(0.008333)
    assert clip.fps == pytest.approx(120.0, rel=1e-4)


def test_crlf_tabs_trailing_whitespace_and_wrapped_frames(tmp_path):
    expected = forward_kinematics(read_bvh(write(tmp_path, chain_bvh("ZYX"), "a.bvh")))[0]
    messy = "\r\n".join(
        "\t" + ln.replace(" ", "\t ") + "  \t" for ln in chain_bvh("ZYX").split("\n")
    )
    clip = read_bvh(write(tmp_path, messy, "crlf.bvh"))
    np.testing.assert_allclose(forward_kinematics(clip)[0], expected, atol=1e-6)
    clip = read_bvh(write(tmp_path, "\ufeff" + chain_bvh("ZYX"), "bom.bvh"))  # byte-order mark
    np.testing.assert_allclose(forward_kinematics(clip)[0], expected, atol=1e-6)
    # Some exporters wrap long frame lines.
    head, frames = chain_bvh("ZYX").split("Frame Time: 0.0333333\n")
    values = frames.split()
    wrapped = head + "Frame Time: 0.0333333\n"
    wrapped += "\n".join(" ".join(values[i : i + 4]) for i in range(0, len(values), 4)) + "\n"
    clip = read_bvh(write(tmp_path, wrapped, "wrapped.bvh"))
    np.testing.assert_allclose(forward_kinematics(clip)[0], expected, atol=1e-6)


# ------------------------------------------------------------------ bad input

GOOD = chain_bvh("ZXY")
FRAME_1 = "1.0 2.0 3.0 0 0 0 90 90 0 0 0 90 0 0 0"
GOOD_FRAME_1 = GOOD.strip().split("\n")[-1]


def _frame_1(text: str) -> str:
    return GOOD.replace(GOOD_FRAME_1, text)


BAD_FILES = {
    "no_hierarchy": (GOOD.replace("HIERARCHY\n", ""), "HIERARCHY"),
    "no_root": (GOOD.replace("ROOT root", "BONE root"), "ROOT"),
    "no_motion": (GOOD.split("MOTION")[0], "MOTION"),
    "missing_brace": (GOOD.replace("      }\n    }\n  }\n}", "      }\n    }\n  }"), "braces"),
    "extra_brace": (GOOD.replace("}\nMOTION", "}\n}\nMOTION"), "HIERARCHY braces"),
    "channel_count": (
        GOOD.replace(
            "CHANNELS 3 Zrotation Xrotation Yrotation\n      JOINT j3",
            "CHANNELS 3 Zrotation Xrotation\n      JOINT j3",
        ),
        "joint 'j2' CHANNELS",
    ),
    "unknown_channel": (
        GOOD.replace(
            "CHANNELS 3 Zrotation Xrotation Yrotation\n      JOINT j3",
            "CHANNELS 3 Zrotation Wrotation Yrotation\n      JOINT j3",
        ),
        "joint 'j2' CHANNELS",
    ),
    "missing_offset": (GOOD.replace("OFFSET 1.0 0 0", ""), "joint 'j2' OFFSET"),
    "bad_offset": (GOOD.replace("OFFSET 1.0 0 0", "OFFSET 1 zero 0"), "joint 'j2' OFFSET"),
    "duplicate_joint": (GOOD.replace("JOINT j3", "JOINT j1"), "JOINT j1"),
    "truncated": (GOOD.replace(GOOD_FRAME_1, ""), "MOTION/Frames"),
    "extra_frames": (GOOD + FRAME_1 + "\n", "MOTION/Frames"),
    "short_frame": (_frame_1(FRAME_1.rsplit(" ", 1)[0]), "MOTION frame 1"),
    "long_frame": (_frame_1(FRAME_1 + " 7"), "MOTION frame 1"),
    "non_numeric": (_frame_1(FRAME_1.replace("90 90", "90 ninety")), "MOTION frame 1"),
    "nan": (_frame_1(FRAME_1.replace("90 90", "90 nan")), "MOTION frame 1"),
    "inf": (_frame_1(FRAME_1.replace("2.0", "inf")), "MOTION frame 1"),
    "zero_frame_time": (GOOD.replace("Frame Time: 0.0333333", "Frame Time: 0"), "Frame Time"),
    "negative_frame_time": (GOOD.replace("0.0333333", "-0.0333333"), "MOTION/Frame Time"),
    "no_frame_time": (GOOD.replace("Frame Time: 0.0333333\n", ""), "MOTION/Frame Time"),
    "bad_frames": (GOOD.replace("Frames: 2", "Frames: two"), "MOTION/Frames"),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_bad_input_errors_name_file_and_field(tmp_path, case):
    text, field = BAD_FILES[case]
    assert text != GOOD
    path = write(tmp_path, text, f"bad_{case}.bvh")
    with pytest.raises(LoosefitInputError) as info:
        read_bvh(path)
    message = str(info.value)
    assert path.name in message
    assert field in info.value.field, message


def test_error_details(tmp_path):
    text, _ = BAD_FILES["short_frame"]
    with pytest.raises(LoosefitInputError) as info:
        read_bvh(write(tmp_path, text, "short.bvh"))
    assert "15 values" in info.value.expected and "14 values" in info.value.found
    text, _ = BAD_FILES["nan"]
    with pytest.raises(LoosefitInputError) as info:
        read_bvh(write(tmp_path, text, "nan.bvh"))
    assert "joint 'j1' Xrotation" in info.value.found
    text, _ = BAD_FILES["truncated"]
    with pytest.raises(LoosefitInputError) as info:
        read_bvh(write(tmp_path, text, "cut.bvh"))
    assert "2 frame lines" in info.value.expected and "1 frame lines" in info.value.found


def test_missing_file(tmp_path):
    with pytest.raises(LoosefitInputError, match="nothere.bvh"):
        read_bvh(tmp_path / "nothere.bvh")


# ------------------------------------------------------------------ real clips


@needs_salsa
def test_salsa_clip_loads():
    clip = read_bvh(SALSA / "61_01.bvh")
    assert clip.num_frames == 2242
    assert clip.fps == pytest.approx(120.0, rel=1e-4)
    assert clip.units_scale == 1.0  # "auto" recognises metres
    for name in ("hip", "lThigh", "lShin", "lFoot", "rShldr"):
        assert name in clip.joint_names
    assert clip.channels[0] == (
        "Xposition",
        "Yposition",
        "Zposition",
        "Zrotation",
        "Yrotation",
        "Xrotation",
    )
    assert clip.channels[clip.index("lShin")] == ("Zrotation", "Xrotation", "Yrotation")
    assert clip.rotations.shape == (2242, clip.num_joints, 3, 3)
    assert np.isfinite(clip.rotations).all()


@needs_salsa
def test_salsa_rest_pose_is_a_t_pose_and_feet_touch_the_ground():
    clip = read_bvh(SALSA / "61_01.bvh")
    rest = rest_positions(clip)
    shoulder, hand = rest[clip.index("lShldr")], rest[clip.index("lHand")]
    assert abs(hand[1] - shoulder[1]) < 0.02  # arm horizontal, Y up
    assert hand[0] - shoulder[0] > 0.3  # left arm along +X
    # In motion, Y is up and the toes stay near y = 0.
    ends = end_site_positions(clip)
    toes = np.minimum(ends[clip.index("lFoot")][:, 1], ends[clip.index("rFoot")][:, 1])
    assert -0.03 < np.median(toes) < 0.1
