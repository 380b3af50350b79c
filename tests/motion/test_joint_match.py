"""Any humanoid BVH skeleton, matched to the avatar without code."""

import dataclasses

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.motion.bvh import read_bvh
from loosefit.motion.joint_maps import DAZ_MAP, load_joint_map_file
from loosefit.motion.retarget import (
    RetargetConfig,
    choose_joint_map,
    resolve_joint_map,
    retarget_bvh,
)
from tests.conftest import SALSA, needs_salsa
from tests.motion.bvh_conventions import (
    ALL_CONVENTIONS,
    CONVENTIONS,
    NAMELESS,
    Convention,
    joint_positions,
    reduced,
    write_convention_bvh,
)

CM = 0.01


@pytest.fixture(scope="module")
def dance(avatar):
    from loosefit.motion.motions import load_motion

    return load_motion("dance:3", avatar, seed=1)  # 90 frames: steps, turns, arm swings


def _write(tmp_path, file, conv, avatar, motion):
    """The motion written in the convention, read back."""
    path = write_convention_bvh(tmp_path / file, conv, avatar.skeleton, motion, avatar.floor_height)
    return read_bvh(path)


def _retarget_error(avatar, motion, conv, clip, config=None):
    """Mean and max distance (m) of the mapped joints from where the motion puts them,
    after the one constant shift that recentring and grounding add."""
    config = config or RetargetConfig(fps=None)
    back = retarget_bvh(clip, avatar.skeleton, avatar.floor_height, config)
    ref = reduced(motion, conv.joints)
    idx = [avatar.skeleton.names.index(a) for a in conv.joints]
    got, want = (joint_positions(avatar.skeleton, m)[:, idx] for m in (back, ref))
    d = got - want  # (T, Jm, 3)
    d -= d.reshape(-1, 3).mean(0)
    err = np.linalg.norm(d, axis=-1)
    return float(err.mean()), float(err.max())


@pytest.mark.parametrize("name", list(ALL_CONVENTIONS))
def test_each_convention_animates_the_same_body_motion(avatar, dance, tmp_path, name):
    conv = ALL_CONVENTIONS[name]
    clip = _write(tmp_path, f"{name}.bvh", conv, avatar, dance)
    match = resolve_joint_map(clip)
    assert match.joint_map.joints == conv.joints
    expected_how = {"cmu_mb": "map cmu_mb", "daz": "map daz", "nameless": "structure"}
    assert set(match.how.values()) == {expected_how.get(name, "name")}
    mean, worst = _retarget_error(avatar, dance, conv, clip)
    print(f"{name}: mean joint error {mean / CM:.2g} cm, max {worst / CM:.2g} cm")
    assert mean < 1 * CM and worst < 2 * CM
    if name == "studio":  # six channels on every joint, in centimetres, arms down at rest
        assert all(len(c) == 6 for c in clip.channels) and clip.units_scale == 0.01
    if name.startswith("studio-"):  # the hips metres from the root still read in centimetres
        assert clip.units_scale == 0.01
    if conv.zero_offsets:  # every bone below the root from the frames
        assert len(clip.meta["bones_from_frames"]) == clip.num_joints - 1


def test_a_wrong_map_is_far_off(avatar, dance, tmp_path):
    # The measure has teeth: Mixamo's arms swapped left for right in a map file.
    conv = CONVENTIONS["mixamo"]
    clip = _write(tmp_path, "m.bvh", conv, avatar, dance)
    swapped = {
        a: s.replace("Left", "@").replace("Right", "Left").replace("@", "Right")
        if "Arm" in a or "Hand" in a or "Shoulder" in a
        else s
        for a, s in conv.joints.items()
    }
    path = tmp_path / "swapped.yaml"
    path.write_text("".join(f"{a}: '{s}'\n" for a, s in swapped.items()))
    cfg = RetargetConfig(fps=None, joint_map=str(path))
    assert _retarget_error(avatar, dance, conv, clip, cfg)[0] > 5 * CM
    # Only the arms below the collars swapped: the map cannot be this skeleton's.
    half = {
        a: s.replace("Left", "@").replace("Right", "Left").replace("@", "Right")
        if "Arm" in a or "Hand" in a
        else s
        for a, s in conv.joints.items()
    }
    path.write_text("".join(f"{a}: '{s}'\n" for a, s in half.items()))
    with pytest.raises(
        LoosefitInputError,
        match=r"swapped\.yaml.*'LeftArm'.*not below "
        r"LeftShoulder 'mixamorig:LeftShoulder'",
    ):
        resolve_joint_map(clip, cfg)


def test_a_skeleton_with_made_up_names_and_z_up_maps_with_a_file(avatar, dance, tmp_path):
    names = {a: f"bone{i}" for i, a in enumerate(NAMELESS.joints)}
    conv = dataclasses.replace(NAMELESS, name="blender", joints=names, up="+z", forward="-y")
    clip = _write(tmp_path, "z.bvh", conv, avatar, dance)
    # As if Y up, nothing stands on legs: refused, naming the file and a map file line.
    with pytest.raises(LoosefitInputError) as err:
        retarget_bvh(clip, avatar.skeleton, avatar.floor_height)
    text = str(err.value)
    assert "z.bvh" in text and "--joint-map" in text and "LeftUpLeg: my_thigh_L" in text
    # ... after the zero pose, on the frames too; with the command that writes a map.
    assert "in the frames or the zero pose (LeftUpLeg: no joint named like" in text
    assert "of the frames tried ([0, 45, 22, 67]), the closest: pelvis" in text
    assert "loosefit inspect-motion z.bvh --write-joint-map my_map.yaml" in text
    # A YAML file: joints and axes.
    path = tmp_path / "map.yaml"
    path.write_text(
        "# my rig\n"
        + "".join(f"{a}: {s}\n" for a, s in names.items())
        + "source_up: +z\nsource_forward: -y\n"
    )
    cfg = RetargetConfig(fps=None, joint_map=str(path))
    match = resolve_joint_map(clip, cfg)
    assert match.joint_map.joints == names and set(match.how.values()) == {"map file"}
    assert _retarget_error(avatar, dance, conv, clip, cfg)[0] < 1 * CM
    # A TOML file with the axes only: the joints matched by structure in those axes.
    path = tmp_path / "axes.toml"
    path.write_text('source_up = "+z"\nsource_forward = "-y"\n')
    cfg = RetargetConfig(fps=None, joint_map=str(path))
    match = resolve_joint_map(clip, cfg)
    assert match.joint_map.joints == names and set(match.how.values()) == {"structure"}
    assert _retarget_error(avatar, dance, conv, clip, cfg)[0] < 1 * CM


def test_a_skeleton_the_matcher_cannot_map_is_a_clear_error(avatar, dance, tmp_path):
    # A one-legged, one-armed skeleton: its right side gone.
    keep = {a: s for a, s in CONVENTIONS["mixamo"].joints.items() if "Right" not in a}
    conv = dataclasses.replace(CONVENTIONS["mixamo"], joints=keep, extras=[])
    clip = _write(tmp_path, "half.bvh", conv, avatar, dance)
    with pytest.raises(LoosefitInputError) as err:
        retarget_bvh(clip, avatar.skeleton, avatar.floor_height)
    text = str(err.value)
    for part in (
        "half.bvh",
        "HIERARCHY",
        "'RightUpLeg'",
        "'RightHand'",
        "no joint named like",
        "--joint-map",
        "LeftUpLeg: my_thigh_L",
        "inspect-motion",
    ):
        assert part in text, part
    assert "LeftUpLeg'" not in text.split("nothing for")[1].split("]")[0]  # found, not missing
    # A chain with no branches at all.
    chain = tmp_path / "snake.bvh"
    joints = "".join(
        f"JOINT s{i}\n{{\nOFFSET 0 10 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n"
        for i in range(5)
    )
    chain.write_text(
        "HIERARCHY\nROOT s\n{\nOFFSET 0 0 0\nCHANNELS 6 Xposition Yposition "
        "Zposition Zrotation Xrotation Yrotation\n"
        + joints
        + "End Site\n{\nOFFSET 0 10 0\n}\n"
        + "}\n" * 6
        + "MOTION\nFrames: 1\nFrame Time: 0.04\n"
        + "0 " * 21
        + "\n"
    )
    with pytest.raises(LoosefitInputError, match=r"snake\.bvh.*no joint branches"):
        resolve_joint_map(read_bvh(chain))


def test_shipped_maps_come_first(tmp_path):
    from tests.motion.test_retarget import write_tpose

    clip = read_bvh(write_tpose(tmp_path / "daz.bvh"))
    assert choose_joint_map(list(clip.joint_names), clip=clip) is DAZ_MAP
    # One DAZ joint renamed: no shipped map fits, the matcher maps it by name.
    path = write_tpose(tmp_path / "calf.bvh")
    path.write_text(path.read_text().replace("lShin", "lCalf"))
    clip = read_bvh(path)
    jmap = choose_joint_map(list(clip.joint_names), clip=clip)
    assert jmap.name == "auto-matched" and jmap.joints["LeftLeg"] == "lCalf"
    assert {a: s for a, s in jmap.joints.items() if a != "LeftLeg"} == {
        a: s for a, s in DAZ_MAP.joints.items() if a != "LeftLeg"
    }


@needs_salsa
def test_the_matcher_finds_the_daz_map_on_the_salsa_files():
    from loosefit.motion.joint_match import match_skeleton
    from loosefit.motion.retarget import axis_change
    from loosefit.motion.skeleton_clip import rest_positions

    clip = read_bvh(SALSA / "61_01.bvh")
    rest = rest_positions(clip) @ axis_change("+y", "+z").T
    match = match_skeleton(clip.joint_names, clip.parents, rest)
    assert match.joint_map.joints == DAZ_MAP.joints
    assert set(match.joint_map.align) == set(DAZ_MAP.align)


def test_map_file_errors_name_the_file_and_the_key(tmp_path):
    names = ["pelvis", "thigh", "knee"]
    cases = {
        "typo.yaml": ("Hips: pelvis\nLeftUpleg: thigh\n", r"typo\.yaml.*'LeftUpleg'.*LeftUpLeg"),
        "absent.yaml": ("Hips: pelvis\nLeftLeg: shin\n", r"absent\.yaml.*'LeftLeg'.*'shin'"),
        "bad.yaml": ("Hips: [pelvis\n", r"bad\.yaml.*valid YAML"),
        "list.yaml": ("- Hips\n", r"list\.yaml.*a table"),
        "nohips.yaml": ("LeftUpLeg: thigh\n", r"nohips\.yaml.*'Hips'"),
        "axis.yaml": ("Hips: pelvis\nsource_up: up\n", r"axis\.yaml.*'source_up'"),
        "align.yaml": ("Hips: pelvis\nalign: [LeftArm]\n", r"align\.yaml.*'align'"),
        "twice.yaml": (
            "Hips: pelvis\nLeftUpLeg: pelvis\n",
            r"twice\.yaml.*Hips and LeftUpLeg both mapped to 'pelvis'",
        ),
        "bad.toml": ("Hips = \n", r"bad\.toml.*valid TOML"),
    }
    for file, (text, pattern) in cases.items():
        (tmp_path / file).write_text(text)
        with pytest.raises(LoosefitInputError, match=pattern):
            load_joint_map_file(tmp_path / file, names)
    with pytest.raises(LoosefitInputError, match=r"missing\.yaml.*no such file"):
        load_joint_map_file(tmp_path / "missing.yaml")
    (tmp_path / "ok.toml").write_text('Hips = "pelvis"\nLeftUpLeg = "thigh"\nLeftLeg = "knee"\n')
    jmap = load_joint_map_file(tmp_path / "ok.toml", names)
    assert jmap.joints["LeftLeg"] == "knee" and jmap.align == ("LeftUpLeg", "LeftLeg")


def test_a_motion_spec_names_the_joint_map(avatar, dance, tmp_path):
    from loosefit.motion.motions import load_motion

    path = write_convention_bvh(
        tmp_path / "m.bvh", CONVENTIONS["mixamo"], avatar.skeleton, dance, avatar.floor_height
    )
    assert load_motion(str(path), avatar).meta["joint_map"] == "auto-matched"
    with pytest.raises(LoosefitInputError, match="'cmu_mb' joint map"):
        load_motion(f"joint-map:cmu_mb:{path}", avatar)
    with pytest.raises(LoosefitInputError, match="joint-map:MAP:MOTION"):
        load_motion("joint-map:cmu_mb:", avatar)


def test_conventions_written_as_declared(avatar, dance, tmp_path):
    # The files carry the conventions' own names, rest poses and units.
    conv: Convention = CONVENTIONS["unreal"]
    clip = _write(tmp_path, "u.bvh", conv, avatar, dance)
    assert clip.joint_names[0] == "pelvis" and "ball_l" in clip.joint_names
    arm = clip.offsets[clip.index("lowerarm_l")]  # A-pose: the upper arm 45 degrees down
    assert arm[0] > 0 and arm[1] < 0 and abs(abs(arm[0]) - abs(arm[1])) < 1e-3
    studio = _write(tmp_path, "s.bvh", CONVENTIONS["studio"], avatar, dance)
    forearm = studio.offsets[studio.index("LowerArm_L")]  # arms down along the sides
    assert forearm[1] < 0 and abs(forearm[0]) < 1e-4 and abs(forearm[2]) < 1e-4


def test_any_tree_is_matched_or_refused_clearly():
    from loosefit.motion.joint_match import match_skeleton

    rng = np.random.default_rng(0)
    words = [
        "Hips",
        "pelvis",
        "Spine",
        "chest",
        "neck",
        "head",
        "HeadTop_End",
        "LeftUpLeg",
        "left_hip",
        "thigh_l",
        "calf_r",
        "RightFoot",
        "ball_l",
        "LeftArm",
        "clavicle_l",
        "RightShoulder",
        "left_wrist",
        "Hand_R",
        "LowerArm_L",
        "bone",
    ]
    for _ in range(300):
        J = int(rng.integers(1, 30))
        parents = np.array([-1] + [int(rng.integers(0, j)) for j in range(1, J)])
        names = [
            f"{rng.choice(words)}{i}" if rng.random() < 0.5 else f"{rng.choice(words)}_{i}"
            for i in range(J)
        ]
        try:
            jmap = match_skeleton(names, parents, rng.normal(size=(J, 3))).joint_map
        except LoosefitInputError:
            continue
        assert len(set(jmap.joints.values())) == len(jmap.joints)


def test_a_joint_map_template_is_filled_in_and_loads(avatar, dance, tmp_path):
    from loosefit.motion.joint_map_files import joint_map_template
    from tests.motion.bvh_conventions import STUDIO_X

    # Matched (a studio rig whose zero pose lies along X, matched on its frames): the
    # template is the match, and retargets as the match does.
    clip = _write(tmp_path, "s.bvh", STUDIO_X, avatar, dance)
    match = resolve_joint_map(clip)
    path = tmp_path / "s.yaml"
    path.write_text(joint_map_template(clip.joint_names, match, "s.bvh", ("+y", "+z")))
    jmap = load_joint_map_file(path, clip.joint_names)
    assert jmap.joints == match.joint_map.joints and jmap.source_up == "+y"
    assert (
        _retarget_error(
            avatar, dance, STUDIO_X, clip, RetargetConfig(fps=None, joint_map=str(path))
        )[0]
        < 1 * CM
    )
    # Not matched (the right side gone): the left guessed by name, the right left to fill in.
    keep = {a: s for a, s in CONVENTIONS["mixamo"].joints.items() if "Right" not in a}
    half = _write(
        tmp_path,
        "h.bvh",
        dataclasses.replace(CONVENTIONS["mixamo"], joints=keep, extras=[]),
        avatar,
        dance,
    )
    text = joint_map_template(half.joint_names, None, "h.bvh")
    assert "LeftUpLeg: 'mixamorig:LeftUpLeg'  # guessed by name" in text
    assert "# RightUpLeg: ?   # thigh" in text and "# RightHand: ?   # wrist" in text
    assert "# The file's joints: mixamorig:Hips," in text
    path.write_text(text)
    jmap = load_joint_map_file(path, half.joint_names)
    assert jmap.joints["Hips"] == "mixamorig:Hips" and "RightUpLeg" not in jmap.joints


def test_a_nameless_rig_whose_zero_pose_does_not_stand_is_matched_on_its_frames(
    avatar, dance, tmp_path
):
    # No names, every bone along X at zero pose, Z up (given), the dancer starting turned
    # 150 degrees away: matched by structure on frame 0, sides told once the frame is
    # turned to face -Y by its feet.
    from scipy.spatial.transform import Rotation

    R = Rotation.from_euler("z", 150, degrees=True).as_matrix().astype(np.float32)
    rot = dance.rotations.copy()
    rot[:, 0] = R @ rot[:, 0]
    away = dataclasses.replace(dance, rotations=rot, root_translation=dance.root_translation @ R.T)
    conv = dataclasses.replace(NAMELESS, bone_axis="x", orient_twist=29.0, up="+z", forward="-y")
    clip = _write(tmp_path, "n.bvh", conv, avatar, away)
    cfg = RetargetConfig(fps=None, source_up="+z")
    match = resolve_joint_map(clip, cfg)
    assert match.joint_map.joints == conv.joints
    assert "turned to face -Y by its feet" in match.notes[-1]
    assert _retarget_error(avatar, away, conv, clip, cfg)[0] < 1 * CM


def test_the_template_never_takes_an_empty_root_and_tells_a_collar_from_an_upper_arm(
    avatar, dance, tmp_path
):
    from loosefit.motion.joint_map_files import joint_map_template
    from tests.motion.bvh_conventions import STUDIO_FAR

    # A studio rig with its right side gone: the matcher refuses it, the names guess.
    keep = {a: s for a, s in STUDIO_FAR.joints.items() if "Right" not in a}
    half = _write(tmp_path, "h.bvh", dataclasses.replace(STUDIO_FAR, joints=keep), avatar, dance)
    with pytest.raises(LoosefitInputError) as err:
        resolve_joint_map(half)
    assert "'LeftArm: UpperArm_L'" not in str(err.value)  # the left side was found
    text = joint_map_template(half.joint_names, None, "h.bvh", None, half.parents)
    jmap = load_joint_map_file(_text(tmp_path / "h.yaml", text), half.joint_names)
    assert jmap.joints["Hips"] == "Hips"  # not joint_Root, a root with no geometry
    assert jmap.joints["LeftShoulder"] == "Shoulder_L" and jmap.joints["LeftArm"] == "UpperArm_L"
    assert "# RightArm: ?" in text


def _text(path, text):
    path.write_text(text)
    return path


def test_a_map_that_cannot_be_the_skeletons_is_refused(avatar, dance, tmp_path):
    from tests.motion.bvh_conventions import STUDIO_FAR

    clip = _write(tmp_path, "s.bvh", STUDIO_FAR, avatar, dance)
    good = dict(STUDIO_FAR.joints)
    cfg = RetargetConfig(fps=None, joint_map=str(tmp_path / "m.yaml"))

    def refused(joints, pattern):
        _text(tmp_path / "m.yaml", "".join(f"{a}: {s}\n" for a, s in joints.items()))
        with pytest.raises(LoosefitInputError, match=pattern):
            resolve_joint_map(clip, cfg)

    _text(tmp_path / "m.yaml", "".join(f"{a}: {s}\n" for a, s in good.items()))
    assert resolve_joint_map(clip, cfg).joint_map.joints == good  # the right map passes
    # The shoulder as the upper arm, the collar left out: the upper arm bends in between.
    wrong = {a: s for a, s in good.items() if a != "LeftShoulder"} | {"LeftArm": "Shoulder_L"}
    refused(
        wrong,
        r"m\.yaml.*'LeftArm'.*'Shoulder_L' to LeftForeArm 'LowerArm_L' passing "
        r"over 'UpperArm_L', where the limb bends by up to \d+ degrees.*map LeftArm "
        r"to 'UpperArm_L'",
    )
    # The pelvis on the root of no geometry above the hips.
    refused(
        good | {"Hips": "joint_Root"},
        r"m\.yaml.*'Hips'.*'joint_Root', a joint with one "
        r"child 'Hips'",
    )
    # A joint the file does not have; two avatar joints on one source joint.
    refused(
        good | {"LeftHand": "Hand_X"},
        r"m\.yaml.*'LeftHand'.*a joint of the motion file.*"
        r"'Hand_X'.*did you mean .*'Hand_L'",
    )
    refused(
        good | {"LeftFoot": "LowerLeg_L"},
        r"m\.yaml.*LeftLeg and LeftFoot both mapped "
        r"to 'LowerLeg_L'",
    )
