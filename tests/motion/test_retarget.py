import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.motion.bvh import read_bvh
from loosefit.motion.retarget import RetargetConfig, axis_change, choose_joint_map, retarget_bvh
from tests.conftest import SALSA, needs_salsa

# A small DAZ-named T-pose skeleton, Y up, facing +Z, arms straight out, legs down.
TPOSE_BVH = """HIERARCHY
ROOT hip
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
  JOINT abdomen
  {
    OFFSET 0 0.10 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT chest
    {
      OFFSET 0 0.15 0
      CHANNELS 3 Zrotation Xrotation Yrotation
      JOINT neck
      {
        OFFSET 0 0.15 0
        CHANNELS 3 Zrotation Xrotation Yrotation
        JOINT head
        {
          OFFSET 0 0.08 0
          CHANNELS 3 Zrotation Xrotation Yrotation
          End Site
          {
            OFFSET 0 0.15 0
          }
        }
      }
{arms}
    }
  }
{legs}
}
MOTION
Frames: 2
Frame Time: 0.0333333
{frames}
"""

ARM = """      JOINT {s}Collar
      {{
        OFFSET {x1} 0.12 0
        CHANNELS 3 Zrotation Xrotation Yrotation
        JOINT {s}Shldr
        {{
          OFFSET {x2} 0 0
          CHANNELS 3 Zrotation Xrotation Yrotation
          JOINT {s}ForeArm
          {{
            OFFSET {x3} 0 0
            CHANNELS 3 Zrotation Xrotation Yrotation
            JOINT {s}Hand
            {{
              OFFSET {x4} 0 0
              CHANNELS 3 Zrotation Xrotation Yrotation
              End Site
              {{
                OFFSET {x5} 0 0
              }}
            }}
          }}
        }}
      }}
"""

LEG = """  JOINT {s}Buttock
  {{
    OFFSET {x1} 0 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT {s}Thigh
    {{
      OFFSET 0 -0.05 0
      CHANNELS 3 Zrotation Xrotation Yrotation
      JOINT {s}Shin
      {{
        OFFSET 0 -0.40 0
        CHANNELS 3 Zrotation Xrotation Yrotation
        JOINT {s}Foot
        {{
          OFFSET 0 -0.40 0
          CHANNELS 3 Zrotation Xrotation Yrotation
          End Site
          {{
            OFFSET 0 -0.04 0.12
          }}
        }}
      }}
    }}
  }}
"""


def write_tpose(path, frames: list[list[float]] | None = None):
    arms = "".join(
        ARM.format(s=s, x1=k * 0.03, x2=k * 0.15, x3=k * 0.27, x4=k * 0.25, x5=k * 0.08)
        for s, k in (("l", 1), ("r", -1))
    )
    legs = "".join(LEG.format(s=s, x1=k * 0.09) for s, k in (("l", 1), ("r", -1)))
    n_channels = 6 + 3 * (4 + 8 + 8)
    if frames is None:
        frames = [[0.0] * n_channels, [0.0] * n_channels]
    rows = "\n".join(" ".join(f"{v:g}" for v in f) for f in frames)
    text = TPOSE_BVH.replace("{arms}", arms).replace("{legs}", legs).replace("{frames}", rows)
    path.write_text(text)
    return path


def test_axis_change_bvh_to_avatar():
    C = axis_change("+y", "+z")
    assert np.allclose(C @ [0, 1, 0], [0, 0, 1])  # up
    assert np.allclose(C @ [0, 0, 1], [0, -1, 0])  # forward: avatar faces -Y
    assert np.allclose(C @ [1, 0, 0], [1, 0, 0])  # the character's left stays +X
    assert np.isclose(np.linalg.det(C), 1.0)
    with pytest.raises(LoosefitInputError, match="perpendicular"):
        axis_change("+y", "-y")


def test_tpose_capture_gives_avatar_tpose(avatar, tmp_path):
    clip = read_bvh(write_tpose(tmp_path / "tpose.bvh"))
    motion = retarget_bvh(clip, avatar.skeleton, avatar.floor_height, RetargetConfig(fps=None))
    body = avatar.pose_motion(motion)
    pos = body.joint_poses[0, :, :3, 3].numpy()
    idx = {n: i for i, n in enumerate(avatar.joint_names)}
    for side, sign in (("Left", 1), ("Right", -1)):
        shoulder, elbow, hand = (pos[idx[f"{side}{b}"]] for b in ("Arm", "ForeArm", "Hand"))
        # Arms horizontal and straight out to the side: a T-pose.
        for a, b in ((shoulder, elbow), (elbow, hand)):
            d = (b - a) / np.linalg.norm(b - a)
            assert d[0] * sign > 0.99, f"{side} arm segment direction {d}"
        # Legs straight down.
        hip, knee, ankle = (pos[idx[f"{side}{b}"]] for b in ("UpLeg", "Leg", "Foot"))
        for a, b in ((hip, knee), (knee, ankle)):
            d = (b - a) / np.linalg.norm(b - a)
            assert d[2] < -0.99, f"{side} leg segment direction {d}"
    # Feet on the floor.
    assert abs(float(body.vertices[0, :, 2].min())) < 0.02
    # The spine and head keep the avatar's own posture: same as at the rest pose.
    assert np.allclose(motion.rotations[0, idx["Spine1"]], np.eye(3), atol=1e-5)


def test_rotating_the_capture_root_turns_the_avatar(avatar, tmp_path):
    n = 6 + 3 * 20
    f0, f1 = [0.0] * n, [0.0] * n
    f1[4] = 90.0  # Yrotation of the root: a quarter turn about the capture's up axis
    clip = read_bvh(write_tpose(tmp_path / "turn.bvh", [f0, f1]))
    motion = retarget_bvh(clip, avatar.skeleton, avatar.floor_height, RetargetConfig(fps=None))
    # Capture Y (up) becomes avatar Z: a 90 degree turn about +Z.
    expected = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]], float)
    assert np.allclose(motion.rotations[1, 0], expected, atol=1e-5)


def test_missing_root_joint_is_an_error(avatar, tmp_path):
    path = write_tpose(tmp_path / "noroot.bvh")
    path.write_text(path.read_text().replace("ROOT hip", "ROOT pelvis"))
    clip = read_bvh(path)
    with pytest.raises(LoosefitInputError, match=r"noroot\.bvh.*HIERARCHY.*'hip'"):
        retarget_bvh(clip, avatar.skeleton, avatar.floor_height, RetargetConfig(joint_map="daz"))


def test_missing_limb_joint_is_an_error(avatar, tmp_path):
    path = write_tpose(tmp_path / "noshin.bvh")
    path.write_text(path.read_text().replace("lShin", "lCalf"))
    config = RetargetConfig(joint_map="daz")  # "auto" now matches lCalf (test_joint_match.py)
    with pytest.raises(LoosefitInputError, match=r"noshin\.bvh.*lShin"):
        retarget_bvh(read_bvh(path), avatar.skeleton, avatar.floor_height, config)


def test_unknown_joint_map_is_an_error():
    with pytest.raises(LoosefitInputError, match="joint_map"):
        choose_joint_map(["hip"], "smpl")


def test_auto_map_detection():
    assert choose_joint_map(["hip", "abdomen", "lThigh", "rThigh"]).name == "daz"
    assert choose_joint_map(["Hips", "LeftUpLeg", "RightUpLeg", "Spine"]).name == "cmu_mb"


@needs_salsa
def test_salsa_clip_retargets_to_plausible_dance(avatar):
    clip = read_bvh(SALSA / "61_01.bvh")
    motion = retarget_bvh(clip, avatar.skeleton, avatar.floor_height)
    assert motion.fps == 30.0
    assert motion.num_frames == int(np.floor((clip.num_frames - 1) / clip.fps * 30 + 1e-9)) + 1
    body = avatar.pose_motion(motion)
    v = body.vertices.numpy()
    lowest = v[:, :, 2].min(1)
    # Feet on the floor most of the time, never deep below it, no flying.
    assert np.median(np.abs(lowest)) < 0.03 and lowest.min() > -0.06 and lowest.max() < 0.15
    # Head above hips in every frame, at a standing height.
    pos = body.joint_poses[:, :, :3, 3].numpy()
    head, hips = pos[:, avatar.joint_names.index("Head")], pos[:, 0]
    assert (head[:, 2] > hips[:, 2] + 0.4).all()
    # Knees bend forward, never backward past straight: angle of hip-knee-ankle
    idx = {n: i for i, n in enumerate(avatar.joint_names)}
    for side in ("Left", "Right"):
        thigh = pos[:, idx[f"{side}Leg"]] - pos[:, idx[f"{side}UpLeg"]]
        shin = pos[:, idx[f"{side}Foot"]] - pos[:, idx[f"{side}Leg"]]
        cos = (
            (thigh * shin).sum(-1) / np.linalg.norm(thigh, axis=-1) / np.linalg.norm(shin, axis=-1)
        )
        assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 120


BALLET = SALSA.parent / "cmu-ballet"


def test_dancer_height_is_measured_standing_on_the_frames(tmp_path):
    # The T-pose's head joint 0.48 m above the hips, its ankles 0.85 m below them: 1.33 m
    # above the ankles at the most extended frame, over HEAD_ANKLE_TO_HEIGHT.
    from loosefit.motion.capture_measure import HEAD_ANKLE_TO_HEIGHT
    from loosefit.motion.retarget import measure_source_height, source_height

    clip = read_bvh(write_tpose(tmp_path / "t.bvh"), units="m")
    measure = measure_source_height(clip)
    assert measure.height == pytest.approx(1.33 / HEAD_ANKLE_TO_HEIGHT, rel=1e-5)
    assert measure.frame == 0 and "above the ankles at frame 0" in measure.how
    assert source_height(read_bvh(tmp_path / "t.bvh", scale=0.5))[0] == pytest.approx(
        measure.height / 2
    )


def test_a_dancer_who_never_stands_straight_is_measured_by_the_legs(tmp_path):
    from loosefit.motion.capture_measure import LEG_TO_HEIGHT
    from loosefit.motion.retarget import measure_source_height

    n = 6 + 3 * 20
    crouch = [0.0] * n
    crouch[6 + 3 * 0 + 1] = 80.0  # abdomen folds forward (Xrotation): the head comes down
    clip = read_bvh(write_tpose(tmp_path / "c.bvh", [crouch, crouch]), units="m")
    measure = measure_source_height(clip)
    assert measure.height == pytest.approx(0.80 / LEG_TO_HEIGHT, rel=1e-4)
    assert "never stands straight" in measure.how


def test_a_dancer_read_in_the_wrong_unit_is_refused_with_height_and_options(avatar, tmp_path):
    path = write_tpose(tmp_path / "t.bvh")
    with pytest.raises(LoosefitInputError) as err:
        retarget_bvh(read_bvh(path, units="mm"), avatar.skeleton, avatar.floor_height)
    text = str(err.value)
    assert "t.bvh" in text and "units" in text and "0.00 m" in text and "read in mm" in text
    assert "at frame 0" in text  # the frame it was measured on
    # The unit that makes a dancer of it, named; no --scale where a unit does it.
    assert "read in m it is 1.56 m: --units m" in text and "units:m:t.bvh" in text
    assert "--scale" not in text
    # Read right, or with the check off, it goes through.
    retarget_bvh(read_bvh(path, units="m"), avatar.skeleton, avatar.floor_height)
    cfg = RetargetConfig(check_height=False)
    retarget_bvh(read_bvh(path, units="mm"), avatar.skeleton, avatar.floor_height, cfg)


def test_a_height_only_a_scale_fixes_names_the_scale_and_none_names_neither(avatar, tmp_path):
    import dataclasses

    from loosefit.motion.motions import load_motion
    from tests.motion.bvh_conventions import CONVENTIONS, write_convention_bvh

    motion = load_motion("idle", avatar).slice(0, 8)

    def refusal(units_per_metre: float) -> str:
        conv = dataclasses.replace(CONVENTIONS["daz"], units=units_per_metre)
        path = write_convention_bvh(
            tmp_path / "d.bvh", conv, avatar.skeleton, motion, avatar.floor_height
        )
        with pytest.raises(LoosefitInputError) as err:
            retarget_bvh(read_bvh(path), avatar.skeleton, avatar.floor_height)
        return str(err.value)

    # In inches (63 units tall, guessed centimetres: a 0.6 m dancer): --scale 0.0254.
    text = refusal(1 / 0.0254)
    assert "read in cm" in text and "in inches it is 1.60 m: --scale 0.0254" in text
    # Five units a metre: a 7.8 m giant in metres, 8 cm in centimetres; no unit, inches
    # or feet make a dancer of it: neither --units nor --scale, but how to look.
    text = refusal(5.0)
    assert "--scale" not in text and "--units" not in text
    assert "the measure itself may be wrong" in text and "--sheet" in text


def test_motion_specs_set_a_bvh_files_unit(avatar, tmp_path):
    from loosefit.motion.motions import load_motion

    path = str(write_tpose(tmp_path / "t.bvh"))
    assert load_motion(f"units:m:{path}", avatar).meta["units_scale"] == 1.0
    assert load_motion(f"scale:1.1:{path}", avatar).meta["units_scale"] == pytest.approx(1.1)
    with pytest.raises(LoosefitInputError, match="1.2-2.2 m tall"):
        load_motion(f"units:cm:{path}", avatar)
    for bad in (f"units:ft:{path}", f"scale:-1:{path}", f"scale:x:{path}", "units:cm:"):
        with pytest.raises(LoosefitInputError, match="motion"):
            load_motion(bad, avatar)


@pytest.mark.skipif(
    not BALLET.is_dir(), reason="../shared/mocap/cmu-ballet is not present beside the repository"
)
def test_the_ballet_clips_units_are_right(avatar):
    # cmu-ballet is in the converter's own unit. Its dancer stands with the head 141 units
    # above the ankles (legs 82.2 units hip to ankle), and a dancer's legs are 0.8 m: the
    # unit is the centimetre, which the guess finds. (The README's 1/128 m is the salsa
    # files' rescaling: a 1.34 m dancer there.)
    from loosefit.motion.motions import load_motion
    from loosefit.motion.retarget import source_height

    clip = read_bvh(BALLET / "05_02.bvh")
    assert clip.units_scale == 0.01
    assert 1.6 < source_height(clip)[0] < 1.8  # the head 1.41 m above the ankles at frame 0
    with pytest.raises(
        LoosefitInputError,
        match=r"1\d\d\.\d\d m \(head 141 m above the ankles "
        r"at frame 0.*read in cm it is 1\.66 m: --units cm",
    ):
        load_motion(f"units:m:{BALLET / '05_02.bvh'}", avatar)
    # Read in any accepted unit, the motion on the avatar is the same (legs set the scale).
    a = load_motion(str(BALLET / "05_02.bvh"), avatar, max_frames=20)
    b = load_motion(f"scale:0.0078125:{BALLET / '05_02.bvh'}", avatar, max_frames=20)
    np.testing.assert_allclose(a.root_translation, b.root_translation, atol=1e-5)
    np.testing.assert_allclose(a.rotations, b.rotations, atol=1e-5)  # float32 positions
