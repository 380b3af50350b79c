import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.fitting.place import carry_rigidly, fit_skirt
from loosefit.sequence import GarmentSequence


@pytest.fixture(scope="module")
def dressed(avatar):
    motion = avatar.rest_motion(4)
    skirt = fit_skirt(avatar)
    g = carry_rigidly(skirt, avatar.pose_motion(motion), avatar).numpy()
    return GarmentSequence(motion, skirt, g, {"rig": "cmu_mb", "shape": avatar.shape}, "rigid")


def test_round_trip(dressed, tmp_path):
    path = dressed.save(tmp_path / "seq.npz")
    back = GarmentSequence.load(path)
    assert np.array_equal(back.garment_vertices, dressed.garment_vertices)
    assert np.array_equal(back.motion.rotations, dressed.motion.rotations)
    assert np.array_equal(back.garment.faces, dressed.garment.faces)
    assert back.avatar == dressed.avatar and back.source == "rigid"
    assert not list(tmp_path.glob("*partial*"))


def test_wrong_vertex_count_is_rejected(dressed):
    with pytest.raises(LoosefitInputError, match=r"garment_vertices.*shape \(4, \d+, 3\)"):
        GarmentSequence(
            dressed.motion, dressed.garment, dressed.garment_vertices[:, :-1], dressed.avatar
        )


def test_nan_is_rejected_with_its_frame(dressed):
    g = dressed.garment_vertices.copy()
    g[2, 5, 1] = np.nan
    with pytest.raises(LoosefitInputError, match=r"garment_vertices.*NaN.*first at \(2, 5, 1\)"):
        GarmentSequence(dressed.motion, dressed.garment, g, dressed.avatar)


def test_foreign_file_is_rejected(tmp_path):
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    with pytest.raises(LoosefitInputError, match=r"other\.npz.*format"):
        GarmentSequence.load(tmp_path / "other.npz")
    with pytest.raises(LoosefitInputError, match="no such file"):
        GarmentSequence.load(tmp_path / "missing.npz")


def test_a_kept_body_is_the_one_the_sequence_would_pose(dressed, avatar, monkeypatch):
    import loosefit.body.avatar

    posed = GarmentSequence(
        dressed.motion, dressed.garment, dressed.garment_vertices, dressed.avatar
    )
    expected = posed.body_vertices  # posed by the sequence itself, on a new avatar
    kept = GarmentSequence(
        dressed.motion, dressed.garment, dressed.garment_vertices, dressed.avatar
    )
    kept.keep_body(avatar, avatar.pose_motion(dressed.motion))

    def no_new_avatar(*_args, **_kwargs):
        raise AssertionError("the avatar was built again")

    monkeypatch.setattr(loosefit.body.avatar, "Avatar", no_new_avatar)
    np.testing.assert_array_equal(kept.body_vertices, expected)
    np.testing.assert_array_equal(kept.body_faces, posed.body_faces)
    assert kept.body_skin.joint_names == posed.body_skin.joint_names
    np.testing.assert_array_equal(kept.body_skin.joint_poses, posed.body_skin.joint_poses)
