"""SMPL-family pose files (AMASS-style .npz) as motions."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from loosefit.errors import LoosefitInputError
from loosefit.geometry.rotations import matrix_to_axis_angle, rotation_angle, rotation_between
from loosefit.motion.joint_maps import LIMBS
from loosefit.motion.retarget import RetargetConfig, axis_change
from loosefit.motion.smpl import (
    SMPL_END_OFFSETS,
    SMPL_JOINTS,
    SMPL_OFFSETS,
    SMPL_PARENTS,
    read_smpl_npz,
    template_from_skeleton,
)
from tests.motion.bvh_conventions import CONVENTIONS, joint_positions, motion_error, reduced

CM = 0.01
SMPL_MAP = CONVENTIONS["smpl"].joints  # avatar joint -> SMPL joint
Z_UP = Rotation.from_euler("x", 90, degrees=True).as_matrix()  # SMPL's Y up -> AMASS's Z up


@pytest.fixture(scope="module")
def dance(avatar):
    from loosefit.motion.motions import load_motion

    return load_motion("dance:3", avatar, seed=1)


def smpl_arrays(avatar, motion, width=156, world=Z_UP):
    """(poses (T, width), trans (T, 3)) that SMPL's template skeleton, retargeted onto the
    avatar, turns into ``reduced(motion, SMPL_MAP)`` again: each avatar limb's rest
    alignment to the template as the retargeting measures it, undone.

    ``world`` turns SMPL's Y-up body frame into the data set's world (AMASS: Z up)."""
    sk = avatar.skeleton
    names, heads, tails = sk.names, sk.heads.astype(np.float64), sk.tails.astype(np.float64)
    C = axis_change("+y", "+z").astype(np.float64)  # SMPL body frame -> avatar axes
    rest = np.zeros((22, 3))
    for j, p in enumerate(SMPL_PARENTS):
        rest[j] = SMPL_OFFSETS[j] + (rest[p] if p >= 0 else 0)
    rest = rest @ C.T
    to_smpl = {a: SMPL_JOINTS.index(s) for a, s in SMPL_MAP.items()}

    def below(b, ancestor):
        while b >= 0:
            b = SMPL_PARENTS[b]
            if b == ancestor:
                return True
        return False

    # 1. The rest alignment of each avatar bone (retarget_bvh's step 1).
    A = np.tile(np.eye(3), (len(names), 1, 1))
    for a, an in enumerate(names):
        p = sk.parents[a]
        A[a] = A[p] if p >= 0 else np.eye(3)
        if an not in LIMBS or an not in to_smpl:
            continue
        b = to_smpl[an]
        kids = [c for c in sk.children(a) if names[c] in to_smpl and below(to_smpl[names[c]], b)]
        if kids:
            c = min(kids, key=lambda c: np.linalg.norm(heads[c] - tails[a]))
            d_av, d_src = heads[c] - heads[a], rest[to_smpl[names[c]]] - rest[b]
        elif b in SMPL_END_OFFSETS:
            d_av, d_src = tails[a] - heads[a], C @ SMPL_END_OFFSETS[b]
        else:
            continue
        A[a] = rotation_between(d_av[None], d_src[None])[0]
    # 2. The SMPL joints' world rotations from rest, then local ones.
    ref = reduced(motion, SMPL_MAP)
    T = motion.num_frames
    W = np.zeros((T, len(names), 3, 3))
    for j, p in enumerate(sk.parents):
        r = ref.rotations[:, j].astype(np.float64)
        W[:, j] = r if p < 0 else W[:, p] @ r
    Q = np.zeros((T, 22, 3, 3))
    for a, b in to_smpl.items():
        Q[:, b] = C.T @ W[:, names.index(a)] @ A[names.index(a)].T @ C
    local = Q.copy()
    for b, p in enumerate(SMPL_PARENTS):
        if p >= 0:
            local[:, b] = np.swapaxes(Q[:, p], -1, -2) @ Q[:, b]
    local[:, 0] = world @ Q[:, 0]

    # 3. The root's path, undoing the retargeting's leg-length scale.
    def leg(x, hip, knee, ankle):
        return np.linalg.norm(x[knee] - x[hip]) + np.linalg.norm(x[ankle] - x[knee])

    scale = leg(heads, *(names.index(n) for n in ("LeftUpLeg", "LeftLeg", "LeftFoot")))
    scale /= leg(rest, 1, 4, 7)  # SMPL's left hip, knee, ankle
    trans = (world @ C.T @ ref.root_translation.astype(np.float64).T).T / scale - SMPL_OFFSETS[0]
    poses = np.zeros((T, width))
    poses[:, :66] = matrix_to_axis_angle(local).reshape(T, 66)
    return poses, trans


def _save(path, poses, trans, **extra):
    np.savez(
        path, poses=poses, trans=trans, betas=np.zeros(16), gender=np.array("neutral"), **extra
    )
    return path


@pytest.mark.parametrize(
    "width, world, rate",
    [(156, Z_UP, "mocap_framerate"), (165, Z_UP, "mocap_frame_rate"), (72, np.eye(3), "fps")],
)
def test_an_smpl_npz_round_trips_to_the_same_motion(avatar, dance, tmp_path, width, world, rate):
    from loosefit.motion.motions import load_motion

    poses, trans = smpl_arrays(avatar, dance, width, world)
    path = _save(tmp_path / f"amass_{width}.npz", poses, trans, **{rate: np.array(30.0)})
    clip = read_smpl_npz(path)
    up = "+z" if world is Z_UP else "+y"
    assert clip.meta["report"]["up"].startswith(f"{up} in the file's world (detected")
    back = load_motion(str(path), avatar)
    assert back.meta["joint_map"] == "auto-matched" and back.num_frames == dance.num_frames
    mean, worst = motion_error(avatar, dance, back, SMPL_MAP)
    print(f"SMPL {width} ({up} up): mean joint error {mean / CM:.2g} cm, max {worst / CM:.2g} cm")
    assert mean < 1 * CM and worst < 2 * CM
    # The up axis given rather than found: the same; a wrong one lays the dancer down.
    given = load_motion(str(path), avatar, retarget=RetargetConfig(smpl_up=up))
    assert np.allclose(given.rotations, back.rotations, atol=1e-6)
    with pytest.raises(LoosefitInputError, match="does not stand"):  # the pose check
        load_motion(str(path), avatar, retarget=RetargetConfig(smpl_up="+x"))
    wrong = load_motion(str(path), avatar, retarget=RetargetConfig(smpl_up="+x", check_pose=False))
    assert motion_error(avatar, dance, wrong, SMPL_MAP)[0] > 10 * CM


def test_a_knee_bend_on_left_knee_bends_the_avatars_left_leg(avatar, tmp_path):
    from loosefit.motion.motions import load_motion

    T = 10
    poses = np.zeros((T, 72))
    poses[:, :3] = [np.pi / 2, 0, 0]  # AMASS: the Y-up body stood up in a Z-up world
    poses[:, 4 * 3] = np.linspace(0, np.pi / 3, T)  # left_knee about x (left): 0 to 60 degrees
    path = _save(tmp_path / "knee.npz", poses, np.zeros((T, 3)), mocap_framerate=np.array(30.0))
    motion = load_motion(str(path), avatar)
    names = list(motion.joint_names)
    rot = motion.rotations.astype(np.float64)
    angles = np.degrees(rotation_angle(rot[:1], rot))  # (T, J) each joint's turn from frame 0
    assert angles[-1, names.index("LeftLeg")] == pytest.approx(60, abs=0.1)
    assert np.delete(angles, names.index("LeftLeg"), axis=1).max() < 0.1
    pos = joint_positions(avatar.skeleton, motion)
    knee, ankle = names.index("LeftLeg"), names.index("LeftFoot")
    shin0, shin1 = pos[0, ankle] - pos[0, knee], pos[-1, ankle] - pos[-1, knee]
    assert shin1[1] - shin0[1] > 0.15 and shin1[2] > shin0[2]  # the foot goes back (+y) and up


def test_loosefit_and_smpl_npz_files_are_told_apart(avatar, tmp_path):
    from loosefit.motion.motions import load_motion

    saved = load_motion("spin", avatar, max_frames=5)
    saved.save(tmp_path / "saved.npz")
    assert load_motion(str(tmp_path / "saved.npz"), avatar).meta == {}  # read, not retargeted
    _save(tmp_path / "smpl.npz", np.zeros((5, 72)), np.zeros((5, 3)), fps=np.array(30.0))
    assert load_motion(str(tmp_path / "smpl.npz"), avatar).meta["joint_map"] == "auto-matched"
    np.savez(tmp_path / "other.npz", positions=np.zeros((5, 3)))
    with pytest.raises(LoosefitInputError, match=r"other\.npz.*loosefit motion.*SMPL.*positions"):
        load_motion(str(tmp_path / "other.npz"), avatar)


def test_bad_smpl_files_name_the_file_and_the_field(tmp_path):
    T = 4
    ok = {"poses": np.zeros((T, 156)), "trans": np.zeros((T, 3)), "mocap_framerate": 60.0}
    nan = np.zeros((T, 156))
    nan[2, 7] = np.nan
    cases = {
        "width": ({"poses": np.zeros((T, 70))}, r"'poses'.*\(T, 72 \| 156 \| 165\).*\(4, 70\)"),
        "flat": ({"poses": np.zeros(156)}, r"'poses'.*\(156,\)"),
        "trans": ({"trans": np.zeros((T, 2))}, r"'trans'.*\(4, 3\).*\(4, 2\)"),
        "frames": ({"trans": np.zeros((T + 1, 3))}, r"'trans'.*\(4, 3\).*\(5, 3\)"),
        "nan": ({"poses": nan}, r"'poses'.*finite.*nan at frame 2, column 7"),
        "naninf": ({"trans": np.full((T, 3), np.inf)}, r"'trans'.*finite.*inf at frame 0"),
        "rate": ({"mocap_framerate": 0.0}, r"'mocap_framerate'.*a positive frame rate"),
        "text": ({"poses": np.array(["a"] * T)}, r"'poses'.*numbers.*dtype"),
        "object": ({"poses": np.array([None] * T, dtype=object)}, r"'poses'.*pickled object"),
    }
    for name, (change, pattern) in cases.items():
        np.savez(tmp_path / f"{name}.npz", **{**ok, **change})
        with pytest.raises(LoosefitInputError, match=rf"{name}\.npz.*{pattern}"):
            read_smpl_npz(tmp_path / f"{name}.npz")
    np.savez(tmp_path / "norate.npz", poses=ok["poses"], trans=ok["trans"])
    with pytest.raises(LoosefitInputError, match=r"norate\.npz.*'mocap_framerate'.*fps.*none"):
        read_smpl_npz(tmp_path / "norate.npz")
    np.savez(tmp_path / "notrans.npz", poses=ok["poses"], mocap_framerate=60.0)
    with pytest.raises(LoosefitInputError, match=r"notrans\.npz.*'trans'"):
        read_smpl_npz(tmp_path / "notrans.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(LoosefitInputError, match=r"junk\.npz.*readable \.npz"):
        read_smpl_npz(tmp_path / "junk.npz")


def test_inspect_motion_reads_smpl(avatar, dance, tmp_path):
    from loosefit.motion.inspect import inspect_motion

    poses, trans = smpl_arrays(avatar, dance)
    path = _save(tmp_path / "amass.npz", poses, trans, mocap_framerate=np.array(30.0))
    text = inspect_motion(path).format()
    parts = (
        "amass.npz",
        "frames: 90 at 30 fps",
        "units: m (SMPL)",
        "SMPL-H, 52 joints",
        "up: +z in the file's world (detected",
        "left_knee",
        "LeftLeg",
        "auto-matched",
    )
    for part in parts:
        assert part in text, (part, text)


def test_the_template_skeleton_is_the_avatar_s_own_in_a_t_pose(avatar):
    """No SMPL number ships: the template is the default avatar's joints (rounded to 0.1 mm),
    the arms straight and level, each bone as long as the avatar's."""
    offsets, ends = template_from_skeleton(avatar.skeleton)
    np.testing.assert_allclose(SMPL_OFFSETS, offsets, atol=5.1e-5)
    assert set(ends) == set(SMPL_END_OFFSETS)
    for j, e in ends.items():
        np.testing.assert_allclose(SMPL_END_OFFSETS[j], e, atol=5.1e-5)
    sk = avatar.skeleton
    for side, sign in (("left", 1), ("right", -1)):
        for smpl, bone in ((f"{side}_elbow", "Arm"), (f"{side}_wrist", "ForeArm")):
            o = offsets[SMPL_JOINTS.index(smpl)]
            j = sk.index(side.capitalize() + bone)
            assert o[0] * sign > 0 and np.allclose(o[1:], 0)  # level, along the body's side
            assert np.linalg.norm(o) == pytest.approx(
                np.linalg.norm(sk.tails[j] - sk.heads[j]), abs=1e-4
            )
    knee, hip = SMPL_JOINTS.index("left_knee"), SMPL_JOINTS.index("left_hip")
    thigh = sk.heads[sk.index("LeftLeg")] - sk.heads[sk.index("LeftUpLeg")]
    assert np.linalg.norm(offsets[knee]) == pytest.approx(np.linalg.norm(thigh), abs=1e-4)
    x, y, z = sk.heads[sk.index("LeftUpLeg")] - sk.heads[sk.index("Hips")]  # Z up, -Y front
    np.testing.assert_allclose(offsets[hip], [x, z, -y], atol=1e-6)  # SMPL's: Y up, +Z front
