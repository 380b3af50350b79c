import pytest

from loosefit.errors import LoosefitInputError
from loosefit.motion.joint_maps import (
    AVATAR_JOINTS,
    CMU_MB_MAP,
    DAZ_MAP,
    JOINT_MAPS,
    LIMBS,
    is_map_file,
    load_joint_map_file,
)


def test_the_shipped_maps_name_avatar_joints():
    assert set(JOINT_MAPS) == {"daz", "cmu_mb"}
    assert CMU_MB_MAP.joints == {n: n for n in AVATAR_JOINTS}
    assert set(DAZ_MAP.joints) <= set(AVATAR_JOINTS)
    # sided templates expand to both sides, the side's letter in front
    assert DAZ_MAP.joints["LeftUpLeg"] == "lThigh" and DAZ_MAP.joints["RightUpLeg"] == "rThigh"
    assert DAZ_MAP.joints["LHipJoint"] == "lButtock" and DAZ_MAP.joints["RHipJoint"] == "rButtock"
    assert len(DAZ_MAP.joints) == 5 + 2 * 8
    assert set(DAZ_MAP.align) <= set(DAZ_MAP.joints) and "LeftToeBase" not in DAZ_MAP.align


def test_map_files_are_told_by_their_suffix():
    assert is_map_file("maps/rig.yaml") and is_map_file("RIG.YML") and is_map_file("r.toml")
    assert not is_map_file("daz") and not is_map_file("rig.json")


def _write(tmp_path, text, name="map.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_map_file_aligns_its_mapped_limbs_by_default(tmp_path):
    path = _write(tmp_path, "Hips: pelvis\nLeftLeg: calf_l\nLeftUpLeg: thigh_l\nSpine: spine\n")
    jmap = load_joint_map_file(path, ["pelvis", "thigh_l", "calf_l", "spine"])
    assert jmap.name == str(path)
    assert jmap.joints == {
        "Hips": "pelvis",
        "LeftLeg": "calf_l",
        "LeftUpLeg": "thigh_l",
        "Spine": "spine",
    }
    assert jmap.align == ("LeftUpLeg", "LeftLeg")  # the limbs, in LIMBS' order, not the file's
    assert all(a in LIMBS for a in jmap.align)
    assert jmap.source_up is None and jmap.source_forward is None


def test_a_toml_map_with_its_own_align_and_axes(tmp_path):
    text = 'Hips = "pelvis"\nLeftArm = "upperarm_l"\nalign = ["LeftArm"]\nsource_up = "+z"\n'
    jmap = load_joint_map_file(_write(tmp_path, text, "map.toml"))
    assert jmap.align == ("LeftArm",) and jmap.source_up == "+z"


def test_a_map_of_axes_alone_keeps_the_automatic_matching(tmp_path):
    jmap = load_joint_map_file(_write(tmp_path, "source_up: -z\nsource_forward: +x\n"))
    assert jmap.joints == {} and jmap.align == ()
    assert (jmap.source_up, jmap.source_forward) == ("-z", "+x")


@pytest.mark.parametrize(
    ("text", "field", "found"),
    [
        ("Hips: pelvis\nLeftThigh: t\n", "LeftThigh", "'LeftThigh'"),
        ("LeftUpLeg: thigh_l\n", "Hips", "no Hips line"),
        ("Hips: pelvis\nHead: 3\n", "Head", "3"),
        ("Hips: pelvis\nSpine: s\nSpine1: s\n", "Spine and Spine1", "Spine and Spine1 both"),
        ("Hips: pelvis\nalign: [LeftArm]\n", "align", "['LeftArm']"),
        ("Hips: pelvis\nalign: LeftArm\n", "align", "'LeftArm'"),
        ("Hips: pelvis\nsource_up: up\n", "source_up", "'up'"),
        ("- Hips\n- pelvis\n", "<file>", "list"),
        ("Hips: [unclosed\n", "<file>", ""),
    ],
)
def test_a_bad_map_file_is_refused_naming_its_key(tmp_path, text, field, found):
    with pytest.raises(LoosefitInputError) as err:
        load_joint_map_file(_write(tmp_path, text))
    assert err.value.source == str(tmp_path / "map.yaml")
    assert err.value.field == field
    assert err.value.found.startswith(found)


def test_an_unknown_joint_gets_a_suggestion_and_a_missing_source_joint_its_neighbours(tmp_path):
    with pytest.raises(LoosefitInputError, match="did you mean LeftUpLeg"):
        load_joint_map_file(_write(tmp_path, "Hips: pelvis\nLeftUpleg: thigh_l\n"))
    path = _write(tmp_path, "Hips: pelvis\nLeftUpLeg: thigh_L\n")
    with pytest.raises(LoosefitInputError, match="did you mean 'thigh_l'"):
        load_joint_map_file(path, ["pelvis", "thigh_l"])
    with pytest.raises(LoosefitInputError, match="no such file"):
        load_joint_map_file(tmp_path / "missing.yaml")
