"""Retargeting from what a capture shows, whatever its zero pose (bone_directions.py).

Each file is written from a known motion on the avatar in another rig's convention
(tests/motion/bvh_conventions.py): names, units, axes, frame rate, and a zero pose that
stands (T-pose, A-pose, arms down) or does not (every bone along its joint's own local
X or Y axis, joint orients twisted in, the standing orientation in every frame). It is
read back the way ``loosefit animate`` reads it, without a joint map, and must give the
motion back: the hips at their height, every mapped bone pointing the same way.
"""

import dataclasses

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.motion.bone_directions import best_rotation, twist_angle, zero_pose_stands
from loosefit.motion.bvh import read_bvh
from loosefit.motion.motions import load_motion
from loosefit.motion.retarget import RetargetConfig, retarget_bvh
from tests.conftest import SALSA, needs_salsa
from tests.motion.bvh_conventions import (
    CONVENTIONS,
    STUDIO_X,
    joint_positions,
    reduced,
    world_rotations,
    write_convention_bvh,
)

M = 1.0  # units: file units per metre
CM = 100.0
STUDIO_Y = dataclasses.replace(STUDIO_X, name="studio-y", bone_axis="y")

# (label, convention, motion, fps)
CASES = [
    ("studio +X bones, Y up, cm, 30 fps", STUDIO_X, "dance:2", 30),
    ("studio +X bones, Z up, m, 60 fps",
     dataclasses.replace(STUDIO_X, up="+z", forward="-y", units=M), "spin", 60),
    ("studio +Y bones, Y up, cm, 120 fps", STUDIO_Y, "sway", 120),
    ("mixamo T-pose, Y up, cm, 30 fps", CONVENTIONS["mixamo"], "dance:2", 30),
    ("mixamo +X bones, Z up, cm, 60 fps",
     dataclasses.replace(CONVENTIONS["mixamo"], up="+z", forward="-y", bone_axis="x",
                         orient_twist=23.0), "dance:2", 60),
    ("unreal A-pose, Y up, cm, 120 fps", CONVENTIONS["unreal"], "spin", 120),
    ("unreal A-pose +X bones, Z up, m, 30 fps",
     dataclasses.replace(CONVENTIONS["unreal"], up="+z", forward="-y", units=M, bone_axis="x",
                         orient_twist=51.0), "sway", 30),
    ("daz T-pose, Y up, cm, 60 fps", CONVENTIONS["daz"], "dance:2", 60),
    ("cmu_mb T-pose, Z up, m, 30 fps",
     dataclasses.replace(CONVENTIONS["cmu_mb"], up="+z", forward="-y"), "sway", 30),
    ("studio arms down, Y up, cm, 30 fps", CONVENTIONS["studio"], "spin", 30),
]  # fmt: skip


def bone_pairs(skeleton, joints) -> list[tuple[int, int]]:
    """(joint, child) avatar index pairs: each mapped joint and the next mapped joint below."""
    names = skeleton.names
    out = []
    for a in joints:
        j = names.index(a)
        p = skeleton.parents[j]
        while p >= 0 and names[p] not in joints:
            p = skeleton.parents[p]
        if p >= 0:
            out.append((p, j))
    return out


def direction_errors(skeleton, want, got, joints) -> dict[str, np.ndarray]:
    """Degrees between each mapped bone's world direction in two motions, per frame."""
    a = joint_positions(skeleton, reduced(want, joints))
    b = joint_positions(skeleton, got)
    out = {}
    for p, j in bone_pairs(skeleton, joints):
        if np.linalg.norm(skeleton.heads[j] - skeleton.heads[p]) < 1e-6:
            continue  # a joint on its parent (the CMU rig's hip joints)
        da, db = a[:, j] - a[:, p], b[:, j] - b[:, p]
        cos = (da * db).sum(-1) / np.linalg.norm(da, axis=-1) / np.linalg.norm(db, axis=-1)
        out[f"{skeleton.names[p]}->{skeleton.names[j]}"] = np.degrees(
            np.arccos(np.clip(cos, -1, 1))
        )
    return out


@pytest.mark.parametrize("label, conv, spec, fps", CASES, ids=[c[0] for c in CASES])
def test_any_rig_gives_the_motion_back(avatar, tmp_path, label, conv, spec, fps):
    motion = load_motion(spec, avatar, fps=fps, seed=3)
    path = write_convention_bvh(
        tmp_path / "clip.bvh", conv, avatar.skeleton, motion, avatar.floor_height
    )
    back = load_motion(str(path), avatar, fps=fps)  # as `loosefit animate` reads it
    assert back.num_frames == motion.num_frames and back.meta["joint_map"] in (
        "auto-matched",
        conv.name,
    )
    stands = conv.bone_axis is None
    assert back.meta["reference"] == ("zero-pose" if stands else "clip"), back.meta
    assert back.meta["axes"].startswith(f"up {conv.up}")
    # The hips at the source's height (the avatar's own skeleton: the same, within 10 %).
    hips, want = back.root_translation[:, 2], motion.root_translation[:, 2]
    assert (np.abs(hips - want) < 0.1 * want).all(), np.abs(hips - want).max()
    # Every mapped bone along the source's, on every frame.
    errors = direction_errors(avatar.skeleton, motion, back, conv.joints)
    worst = max(errors, key=lambda k: errors[k].max())
    print(f"{label}: worst bone {worst} {errors[worst].max():.2f} deg")
    assert errors[worst].max() < 10.0, (worst, errors[worst].max())
    # And turned about them as the source's are (the limbs' twist from their bends).
    from loosefit.geometry.rotations import rotation_angle

    idx = [avatar.skeleton.names.index(a) for a in conv.joints]
    want_w = world_rotations(avatar.skeleton, reduced(motion, conv.joints))[:, idx]
    turn = np.degrees(rotation_angle(want_w, world_rotations(avatar.skeleton, back)[:, idx]))
    assert turn.max() < 10.0, (list(conv.joints)[int(np.argmax(turn.max(0)))], turn.max())


def test_the_zero_pose_calibration_on_a_rig_that_does_not_stand_is_refused(avatar, tmp_path):
    # The measure has teeth: calibrated on a zero pose with every bone along X (what
    # retargeting did before), the body comes out contorted, and the pose check says so.
    motion = load_motion("dance:2", avatar, seed=3)
    path = write_convention_bvh(
        tmp_path / "studio.bvh", STUDIO_X, avatar.skeleton, motion, avatar.floor_height
    )
    clip = read_bvh(path)
    cfg = RetargetConfig(fps=None, reference="zero-pose")
    with pytest.raises(LoosefitInputError) as err:
        retarget_bvh(clip, avatar.skeleton, avatar.floor_height, cfg)
    text = str(err.value)
    assert "studio.bvh" in text and "poses" in text and "does not stand" in text
    assert "Head not above Hips in frames 0-" in text
    bad = retarget_bvh(
        clip, avatar.skeleton, avatar.floor_height, dataclasses.replace(cfg, check_pose=False)
    )
    errors = direction_errors(avatar.skeleton, motion, bad, STUDIO_X.joints)
    assert max(e.max() for e in errors.values()) > 45.0


def test_a_rigs_zero_pose_is_told_standing_or_not():
    up, down = np.array([0, 0, 1.0]), np.array([0, 0, -1.0])
    present = {"Hips": 0, "LeftUpLeg": 1, "LeftFoot": 2, "RightUpLeg": 3, "RightFoot": 4, "Head": 5}
    tpose = np.array(
        [[0, 0, 0], [0.1, 0, 0], [0.1, 0, 0], [-0.1, 0, 0], [-0.1, 0, 0], [0, 0, 0]]
    ) + np.stack([0 * up, 0 * up, 0.8 * down, 0 * up, 0.8 * down, 0.6 * up])
    assert zero_pose_stands(tpose, present) == (True, "")
    along_x = np.array(
        [[0, 0, 0], [0.1, 0, 0], [0.9, 0, 0], [-0.1, 0, 0], [-0.9, 0, 0], [0.6, 0, 0]]
    )
    ok, why = zero_pose_stands(along_x, present)
    assert not ok and "the left leg points down" in why and "the torso points up" in why
    mirrored = tpose * [-1, 1, 1]  # facing away: the left thigh on the right
    assert zero_pose_stands(mirrored, present)[1] == "not: the left thigh is on the left"


def test_twist_and_best_rotation_against_brute_force():
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(0)
    axis = np.array([0.3, -0.2, 0.9])
    axis /= np.linalg.norm(axis)
    true = Rotation.from_rotvec(axis * 1.1).as_matrix()
    cues = []
    for w in (1.0, 0.5):
        v = rng.normal(size=3)
        u = (true @ v)[None] + 0.05 * rng.normal(size=(40, 3))  # (T, 3) noisy
        cues.append((v, u, w))
    angle = twist_angle(axis, cues)

    def cost(a):  # what the twist minimises, frame by frame: both off the axis, v unit,
        R = Rotation.from_rotvec(axis * a).as_matrix()  # u of its sine's length
        total = 0.0
        for v, u, w in cues:
            vp = v - (v @ axis) * axis
            vp = R @ (vp / np.linalg.norm(vp))
            for ut in u:
                ut = ut / np.linalg.norm(ut)
                total += w * np.sum((ut - (ut @ axis) * axis - vp) ** 2)
        return total

    grid = np.linspace(-np.pi, np.pi, 3601)
    assert abs(angle - grid[np.argmin([cost(a) for a in grid])]) < 2e-3
    assert abs(angle - 1.1) < 0.05
    # Wahba: exact cues give the rotation back; one direction alone gives None.
    v1, v2 = np.array([1.0, 0, 0]), np.array([0, 1.0, 0])
    R = best_rotation([(v1, (true @ v1)[None].repeat(3, 0), 1.0), (v2, (true @ v2)[None], 1.0)])
    assert np.allclose(R, true, atol=1e-9)
    assert best_rotation([(v1, (true @ v1)[None], 1.0)]) is None


@needs_salsa
def test_salsa_calibrated_on_the_clip_moves_as_on_its_zero_pose(avatar):
    # A standing-rest file, calibrated both ways: the limbs point the same way at every
    # frame (they are matched bone by bone); the torso, calibrated on the clip's average
    # posture rather than on the T-pose, within a constant few degrees. Measured on all
    # 31 CMU clips: limbs 0.0 degrees; torso bones up to 9.3 (salsa, Hips->LowerBack) and
    # 22.7 (ballet 05_09, the pelvis), the rest of the torso 10 at most.
    clip = read_bvh(SALSA / "61_01.bvh")
    a, b = (
        retarget_bvh(clip, avatar.skeleton, avatar.floor_height, RetargetConfig(reference=r))
        for r in ("zero-pose", "clip")
    )
    assert a.meta["reference"] == "zero-pose" and b.meta["reference"] == "clip"
    pa, pb = joint_positions(avatar.skeleton, a), joint_positions(avatar.skeleton, b)
    names = avatar.skeleton.names
    limbs = [
        (f"{S}{x}", f"{S}{y}")
        for S in ("Left", "Right")
        for x, y in (
            ("UpLeg", "Leg"),
            ("Leg", "Foot"),
            ("Arm", "ForeArm"),
            ("ForeArm", "Hand"),
            ("Shoulder", "Arm"),
        )
    ]
    torso = [("Hips", "LowerBack"), ("LowerBack", "Spine1"), ("Spine1", "Neck"), ("Neck", "Head")]
    for pairs, limit in ((limbs, 0.5), (torso, 10.0)):
        for x, y in pairs:
            i, j = names.index(x), names.index(y)
            da, db = pa[:, j] - pa[:, i], pb[:, j] - pb[:, i]
            cos = (da * db).sum(-1) / np.linalg.norm(da, axis=-1) / np.linalg.norm(db, axis=-1)
            err = np.degrees(np.arccos(np.clip(cos, -1, 1)))
            assert err.max() < limit, (x, y, err.max())
