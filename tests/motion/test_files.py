import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.motion.bvh import read_bvh
from loosefit.motion.files import CLIP_READERS, is_capture_file, motion_files, read_clip
from loosefit.motion.retarget import RetargetConfig

TWO_JOINTS = """HIERARCHY
ROOT hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT spine
  {
    OFFSET 0 10 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 20 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.04
0 90 0 0 0 0 0 0 0
5 90 0 0 0 0 0 0 45
"""


def _smpl(path, **fields):
    """An SMPL pose file of two frames (the rest pose), with ``fields`` on top."""
    base = dict(poses=np.zeros((2, 72)), trans=np.zeros((2, 3)), mocap_framerate=30.0)
    np.savez(path, **(base | fields))
    return path


def test_a_bvh_is_read_in_the_units_asked(tmp_path):
    path = tmp_path / "walk.bvh"
    path.write_text(TWO_JOINTS)
    clip = read_clip(path, RetargetConfig(units="cm"))
    assert tuple(clip.joint_names) == ("hips", "spine")
    np.testing.assert_allclose(clip.offsets[1], [0.0, 0.1, 0.0], atol=1e-7)
    scaled = read_clip(path, RetargetConfig(scale=0.5))
    np.testing.assert_allclose(scaled.offsets[1], [0.0, 5.0, 0.0], atol=1e-6)
    same = read_bvh(path, units="cm")
    np.testing.assert_array_equal(clip.rotations, same.rotations)
    np.testing.assert_array_equal(clip.local_translations, same.local_translations)
    assert clip.frame_time == pytest.approx(0.04)


def test_an_smpl_npz_is_a_capture_and_a_loosefit_motion_is_not(tmp_path):
    smpl = _smpl(tmp_path / "amass.npz")
    motion = tmp_path / "motion.npz"
    np.savez(motion, rotations=np.zeros((2, 3, 3, 3)), poses=np.zeros((2, 72)))
    assert is_capture_file(smpl) and not is_capture_file(motion)
    assert is_capture_file(tmp_path / "missing.BVH")  # by its suffix alone
    assert not is_capture_file(tmp_path / "missing.npz")
    assert not is_capture_file(tmp_path / "notes.txt")
    clip = read_clip(smpl)
    assert len(clip.rotations) == 2 and clip.frame_time == pytest.approx(1 / 30)


def test_read_clip_refuses_unknown_suffixes_and_missing_files(tmp_path):
    with pytest.raises(LoosefitInputError) as err:
        read_clip(tmp_path / "walk.fbx")
    assert err.value.field == "suffix" and err.value.found == "'.fbx'"
    assert err.value.expected == f"one of {list(CLIP_READERS)}"
    with pytest.raises(LoosefitInputError, match="expected an existing GLB file, found no such"):
        read_clip(tmp_path / "walk.glb")


def test_a_folder_lists_its_motions_sorted_and_leaves_other_files(tmp_path):
    (tmp_path / "b.bvh").write_text(TWO_JOINTS)
    _smpl(tmp_path / "a.npz")
    np.savez(tmp_path / "c.npz", rotations=np.zeros((1, 2, 3, 3)))
    (tmp_path / "readme.txt").write_text("not a motion")
    (tmp_path / "sub.bvh").mkdir()  # a folder, not a file
    assert [f.name for f in motion_files(tmp_path)] == ["a.npz", "b.bvh", "c.npz"]


def test_a_folder_of_motions_is_refused_with_the_file_at_fault(tmp_path):
    with pytest.raises(LoosefitInputError, match="no such folder"):
        motion_files(tmp_path / "none")
    (tmp_path / "readme.txt").write_text("")
    with pytest.raises(LoosefitInputError, match="found no motion file"):
        motion_files(tmp_path)
    (tmp_path / "spin.bvh").write_text(TWO_JOINTS)
    _smpl(tmp_path / "spin.npz")
    with pytest.raises(LoosefitInputError) as err:
        motion_files(tmp_path)
    assert err.value.field == "spin" and err.value.found == "spin.bvh and spin.npz"
    (tmp_path / "spin.npz").unlink()
    np.savez(tmp_path / "weights.npz", w=np.zeros(3))
    with pytest.raises(LoosefitInputError) as err:
        motion_files(tmp_path)
    assert err.value.source == str(tmp_path / "weights.npz")
    assert err.value.found == "fields ['w']"
