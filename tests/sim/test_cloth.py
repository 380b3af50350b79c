"""The cloth simulator: a tiny skirt on a short motion, plus the pure helpers on synthetic data.

The first run ever compiles Newton's and Warp's CPU kernels (a minute or so,
cached under ~/.cache/warp); after that the whole file takes well under a minute.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from loosefit.body.motions import load_motion
from loosefit.dress import fit_skirt
from loosefit.errors import LoosefitInputError
from loosefit.garment.skirt import SkirtConfig
from loosefit.geometry.query import closest_points
from loosefit.sim.cloth import (
    ClothConfig,
    SimulationError,
    _guard,
    glue_waist,
    glued_points,
    preroll,
    simulate,
    simulate_batch,
    substep_schedule,
)
from loosefit.types import GarmentTemplate, Motion
from tests.meshes import cube

TINY_SKIRT = SkirtConfig(style="aline", rings=8, segments=24)


@pytest.fixture(scope="module")
def tiny(avatar):
    """A coarse skirt, six frames of a spin ramping up, and its simulation."""
    skirt = fit_skirt(avatar, TINY_SKIRT)
    motion = load_motion("spin", avatar).slice(20, 26)
    done = []
    result = simulate(
        avatar, skirt, motion, ClothConfig.tiny(), progress=lambda d, t: done.append((d, t))
    )
    return skirt, motion, result, done


# -- the tiny simulation ------------------------------------------------------------


def test_tiny_skirt_stays_finite_attached_and_outside(avatar, tiny):
    skirt, motion, result, done = tiny
    g = result.garment_vertices
    assert g.shape == (motion.num_frames, skirt.num_vertices, 3) and g.dtype == np.float32
    assert np.isfinite(g).all()
    body = avatar.pose_motion(motion).vertices.numpy()
    faces = avatar.faces.numpy()
    for t in range(motion.num_frames):
        hit = closest_points(body[t], faces, g[t])
        waist = hit.distance[skirt.waist]
        assert waist.max() < 0.01, f"frame {t}: waistband {waist.max():.3f} m off the body"
        assert hit.inside.mean() < 0.005, f"frame {t}: {hit.inside.sum()} vertices inside"
    assert result.quality["inside_max"] < 0.005
    assert result.quality["nan_count"] == 0
    assert done[-1] == (len(done), len(done)) and len(done) == result.preroll_frames + 5


def test_tiny_skirt_hangs_under_gravity(tiny):
    skirt, _, result, _ = tiny
    rings = skirt.vertices.reshape(TINY_SKIRT.rings, TINY_SKIRT.segments, 3)
    settled = result.settled_vertices.reshape(TINY_SKIRT.rings, TINY_SKIRT.segments, 3)
    drop = settled[0, :, 2].mean() - settled[-1, :, 2].mean()
    # An A-line hangs about 10 degrees from vertical: the hem is most of a length below.
    assert drop > 0.8 * TINY_SKIRT.length * math.cos(math.radians(10.0))
    # Gravity pulls it down, never up, relative to the waist.
    assert drop >= (rings[0, :, 2].mean() - rings[-1, :, 2].mean()) - 0.01
    assert result.quality["strain_p99"] < 0.1


def test_simulation_is_deterministic(avatar, tiny):
    skirt, motion, result, _ = tiny
    again = simulate(avatar, skirt, motion, ClothConfig.tiny())
    np.testing.assert_array_equal(again.garment_vertices, result.garment_vertices)


def test_bad_inputs_are_rejected(avatar):
    skirt = fit_skirt(avatar, TINY_SKIRT)
    motion = avatar.rest_motion(3)
    no_waist = GarmentTemplate(
        skirt.vertices,
        skirt.faces,
        skirt.uvs,
        skirt.face_uvs,
        np.zeros(0, np.int64),
        name="nowaist",
    )
    with pytest.raises(LoosefitInputError, match="waist"):
        simulate(avatar, no_waist, motion, ClothConfig.tiny())
    wrong = Motion(
        ("a", "b"), np.tile(np.eye(3, dtype=np.float32), (3, 2, 1, 1)), np.zeros((3, 3)), 30.0
    )
    with pytest.raises(LoosefitInputError, match="joint_names"):
        simulate(avatar, skirt, wrong, ClothConfig.tiny())
    with pytest.raises(LoosefitInputError, match="substeps"):
        ClothConfig(substeps=0)
    with pytest.raises(LoosefitInputError, match="density"):
        ClothConfig(density=-1.0)


# -- pure helpers -------------------------------------------------------------------


def test_preroll_settles_at_the_start_then_blends_into_the_first_frame():
    T, J = 4, 3
    yaw = math.radians(90.0)
    rz = np.array(
        [[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0], [0, 0, 1]]
    )
    rot = np.tile(np.eye(3, dtype=np.float32), (T, J, 1, 1))
    rot[:, 0] = rz
    root = np.tile(np.array([2.0, 1.0, 0.95], np.float32), (T, 1))
    motion = Motion(("r", "a", "b"), rot, root, 30.0)
    r, t, n_settle = preroll(motion, 0.9, settle_seconds=0.5, blend_seconds=0.2)
    assert n_settle == 16 and r.shape == (16 + 6, J, 3, 3) and t.shape == (22, 3)
    np.testing.assert_allclose(r[0, 0], rz, atol=1e-6)  # turned to the motion's heading
    np.testing.assert_allclose(t[0], [2.0, 1.0, 0.9], atol=1e-6)  # on the floor where it starts
    np.testing.assert_allclose(np.diff(t[:n_settle], axis=0), 0.0)
    assert 0.9 < t[-1, 2] < 0.95 and np.all(np.diff(t[n_settle - 1 :, 2]) > 0)
    origin = preroll(motion, 0.9, 0.0, 0.2, settle_at_start=False)
    np.testing.assert_allclose(origin[0][0, 0], np.eye(3), atol=1e-6)
    np.testing.assert_allclose(origin[1][0], [0.0, 0.0, 0.9], atol=1e-6)
    assert origin[2] == 1


def test_substep_schedule_follows_the_fastest_waistband_point():
    T, W = 12, 4
    waist = np.zeros((T, W, 3))
    waist[7:, 2, 0] = 0.05  # one point jumps 5 cm between frames 6 and 7
    n = substep_schedule(waist, substeps=20, max_substeps=60, max_move=0.004, widen=2)
    assert n.shape == (T - 1,) and n.dtype == np.int64
    expected = np.full(T - 1, 20)
    # ceil(5 cm / 4 mm) = 13 < 20: the floor holds everywhere
    np.testing.assert_array_equal(n, expected)
    fast = substep_schedule(waist * 4, substeps=20, max_substeps=60, max_move=0.004, widen=2)
    expected[4:9] = 50  # 20 cm / 4 mm, on the jump and the two frames either side
    np.testing.assert_array_equal(fast, expected)
    capped = substep_schedule(waist * 10, substeps=20, max_substeps=60, max_move=0.004, widen=0)
    assert capped.max() == 60 and (capped == 60).sum() == 1


def test_glue_holds_points_on_a_moving_body():
    v, f = cube(0.4)
    ring = np.array([[0.25 * math.cos(a), 0.25 * math.sin(a), 0.05] for a in np.linspace(0, 6, 12)])
    exact = glue_waist(ring, v, f, None)
    np.testing.assert_allclose(glued_points(exact, v, f), ring, atol=1e-5)
    snug = glue_waist(ring, v, f, 0.01)
    hit = closest_points(v, f, glued_points(snug, v, f))
    np.testing.assert_allclose(hit.distance, 0.01, atol=1e-5)
    assert not hit.inside.any()
    # A rigid motion of the body carries the glued points with it.
    c, s = math.cos(0.7), math.sin(0.7)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    moved = v @ rot.T + [1.0, 2.0, 3.0]
    np.testing.assert_allclose(
        glued_points(exact, moved, f), ring @ rot.T + [1.0, 2.0, 3.0], atol=1e-5
    )


def test_guard_names_the_frame():
    body = np.zeros((4, 3))
    with pytest.raises(SimulationError, match="motion frame 7"):
        _guard(np.array([[np.nan, 0.0, 0.0]]), body, 10.0, "motion frame 7")
    with pytest.raises(SimulationError, match="settle frame 2"):
        _guard(np.array([[20.0, 0.0, 0.0]]), body, 10.0, "settle frame 2")
    _guard(np.array([[5.0, 0.0, 0.0]]), body, 10.0, "fine")


def test_recorded_graphs_replay_exactly(avatar, tiny):
    # A CPU graph does not replay wp.Mesh.refit, so the body is posed outside the graphs:
    # with a moving body, replaying must give what plain launches give.
    skirt, motion, result, _ = tiny
    plain = simulate(avatar, skirt, motion, ClothConfig.tiny(capture=False))
    np.testing.assert_array_equal(plain.garment_vertices, result.garment_vertices)


def test_fast_frames_get_more_substeps_and_replay_exactly(avatar, tiny):
    # The spin's waistband moves ~1-2 cm a frame: at 2 mm a substep those frames need more
    # than 8. Each substep count records its own graphs (the step length is baked in).
    skirt, motion, result, _ = tiny
    config = ClothConfig.tiny(max_substeps=16, substep_waist_move=0.002)
    fine = simulate(avatar, skirt, motion, config)
    assert 8 < fine.stats["substeps_max"] <= 16 and fine.stats["substeps_mean"] > 8
    assert result.stats["substeps_max"] == 8  # the default tiny config: fixed steps
    assert np.isfinite(fine.garment_vertices).all() and fine.quality["inside_max"] < 0.005
    assert not np.array_equal(fine.garment_vertices, result.garment_vertices)
    plain = simulate(avatar, skirt, motion, dataclasses.replace(config, capture=False))
    np.testing.assert_array_equal(plain.garment_vertices, fine.garment_vertices)


class _Kill(Exception):
    pass


def test_killed_run_resumes_from_its_saved_state(avatar, tiny, tmp_path):
    skirt, motion, result, done = tiny
    total = done[-1][1]
    path = tmp_path / "run.npz"
    stop = total - 3  # after the save at frame 2 * every, inside the motion

    def kill(d, t):
        if d == stop:
            raise _Kill

    with pytest.raises(_Kill):
        simulate(avatar, skirt, motion, ClothConfig.tiny(), progress=kill, resume=path,
                 resume_every=4)  # fmt: skip
    assert path.is_file()
    seen = []
    again = simulate(
        avatar, skirt, motion, ClothConfig.tiny(), progress=lambda d, t: seen.append(d),
        resume=path, resume_every=4,
    )  # fmt: skip
    assert seen[0] > 1  # it did not start over
    np.testing.assert_array_equal(again.garment_vertices, result.garment_vertices)
    assert not path.exists()  # removed once the run is whole


def test_resume_keeps_the_skin_anchors_of_the_release(avatar, tiny, tmp_path):
    skirt, motion, _, done = tiny
    config = ClothConfig.tiny(release_depth=1e-4)  # the release on: the cloth is anchored
    whole = simulate(avatar, skirt, motion, config)
    path, stop = tmp_path / "run.npz", done[-1][1] - 3

    def kill(d, t):
        if d == stop:
            raise _Kill

    with pytest.raises(_Kill):
        simulate(avatar, skirt, motion, config, progress=kill, resume=path, resume_every=4)
    with np.load(path) as saved:  # every vertex anchored on each of the five parts
        assert saved["anchor_face_0"].shape == (skirt.num_vertices, 5)
        assert (saved["anchor_face_0"] >= 0).all()
    again = simulate(avatar, skirt, motion, config, resume=path, resume_every=4)
    np.testing.assert_array_equal(again.garment_vertices, whole.garment_vertices)


def test_resume_takes_a_run_saved_without_the_release_it_never_needed(avatar, tiny, tmp_path):
    skirt, motion, result, done = tiny
    path, stop = tmp_path / "run.npz", done[-1][1] - 3

    def kill(d, t):
        if d == stop:
            raise _Kill

    with pytest.raises(_Kill):  # saved without the release
        simulate(avatar, skirt, motion, ClothConfig.tiny(), progress=kill, resume=path,
                 resume_every=4)  # fmt: skip
    seen = []
    again = simulate(avatar, skirt, motion, ClothConfig.tiny(release_depth=0.01), resume=path,
                     resume_every=4, progress=lambda d, t: seen.append(d))  # fmt: skip
    assert seen[0] > 1  # nothing was ever 1 cm inside: the saved frames are the same run's
    np.testing.assert_array_equal(again.garment_vertices, result.garment_vertices)
    assert again.stats["released_frames"] == 0


def test_a_saved_run_the_release_would_have_changed_starts_over():
    from loosefit.sim.cloth import _resumed_release
    from tests.meshes import cube

    v, f = cube(1.0)
    collider = np.stack([v] * 4)  # two frames of preroll, two of motion
    garment = np.array([[[0.0, 0.0, 0.6]], [[0.0, 0.0, 0.2]]], np.float32)  # in, 0.3 m deep
    saved = {"frame": np.int64(3), "garment": garment, "release_depth": np.float64(np.nan)}
    zero = [np.zeros(4, np.int64)]
    config = ClothConfig.tiny(release_depth=0.05)
    args = ([collider], [_release(v, f)], 2, 1 / 30, zero)
    assert _resumed_release(saved, config, *args)[0] is None
    # the same frames at 0.5 m of release depth: taken, with the anchor over the top face
    deep = ClothConfig.tiny(release_depth=0.5)
    release = _release(v, f, depth=0.5)
    kept, _ = _resumed_release(saved, deep, [collider], [release], 2, 1 / 30, zero)
    assert kept is saved and (release.face >= 0).all()
    # a run saved with a release that moved cloth: not taken without it
    moved = {**saved, "release_depth": np.float64(0.05), "released_0": np.array([0, 0, 1, 0])}
    assert _resumed_release(moved, ClothConfig.tiny(), [collider], None, 2, 1 / 30, zero)[0] is None


def test_a_field_at_its_value_from_before_it_existed_stays_out_of_the_run_key(tiny, monkeypatch):
    import loosefit.sim.cloth as cloth

    template = tiny[0]
    body = np.zeros((3, 10, 3), np.float32)
    config = ClothConfig.tiny()
    before = cloth._run_key(body, template, config)
    monkeypatch.setattr(cloth, "RUN_KEY_SINCE", {"jitter": config.jitter})
    assert cloth._run_key(body, template, config) != before  # the field left the key
    other = dataclasses.replace(config, jitter=2 * config.jitter)
    assert cloth._run_key(body, template, other) != cloth._run_key(body, template, config)
    # the release never enters it
    with_release = dataclasses.replace(config, release_depth=0.02)
    assert cloth._run_key(body, template, with_release) == cloth._run_key(body, template, config)


def test_the_run_key_leaves_the_device_out_and_a_cpu_run_keeps_its_key(tmp_path):
    """A clip begun with --device cuda:0 goes on from its resume file with --device cpu
    (and back); a run saved on the CPU before the device left the key still resumes."""
    import loosefit.sim.cloth as cloth
    from loosefit.types import GarmentTemplate

    v = np.arange(18, dtype=np.float32).reshape(6, 3) / 10
    f = np.array([[0, 1, 2], [2, 3, 4], [3, 4, 5]])
    template = GarmentTemplate(v, f, np.zeros((6, 2), np.float32) + 0.5, f, np.array([0, 1]))
    body = np.arange(4 * 10 * 3, dtype=np.float32).reshape(4, 10, 3) / 100  # (T, Vb, 3)
    on_gpu = cloth._run_key(body, template, ClothConfig(device="cuda:0"))
    on_cpu = cloth._run_key(body, template, ClothConfig(device="cpu"))
    assert on_gpu == on_cpu == "b6e1604ee06b5b4e5e3e21cb5cbdd8cc"  # the key before the change
    tiny = ClothConfig.tiny(device="cuda:0")
    assert cloth._run_key(body, template, tiny) == "1d2b5c13b1c0a98b4e23565967ce6374"
    assert cloth._run_key(body, template, dataclasses.replace(tiny, iterations=9)) != on_cpu
    # the resume file a GPU run saved is the CPU run's
    path = tmp_path / "clip.npz"
    cloth._write_resume(path, key=np.array(on_gpu), frame=np.int64(3), seconds=np.float64(1.0))
    assert cloth._read_resume(path, on_cpu, total=10) is not None
    assert cloth._read_resume(path, "another run", total=10) is None


def test_resume_ignores_the_state_of_another_run(avatar, tiny, tmp_path):
    skirt, motion, result, done = tiny
    path = tmp_path / "run.npz"
    np.savez(path, key=np.array("another run"), frame=np.int64(3))
    seen = []
    again = simulate(avatar, skirt, motion, ClothConfig.tiny(), resume=path,
                     progress=lambda d, t: seen.append(d))  # fmt: skip
    assert seen[0] == 1
    np.testing.assert_array_equal(again.garment_vertices, result.garment_vertices)


def test_settle_alone_gives_the_drape_every_clip_starts_from(avatar, tiny):
    from loosefit.model.motion_features import root_frames
    from loosefit.sim.cloth import settle

    skirt, motion, result, _ = tiny
    alone = settle(avatar, skirt, ClothConfig.tiny(), fps=motion.fps)
    # simulate() settles standing where the motion starts, turned to its heading.
    c = ClothConfig.tiny()
    rot, root, _ = preroll(motion, avatar.floor_height, c.settle_seconds, c.blend_seconds)
    import torch

    H, p = root_frames(torch.from_numpy(rot[:1]), torch.from_numpy(root[:1]))
    in_root = (torch.from_numpy(result.settled_vertices)[None] - p[:, None]) @ H
    # The drape is one of many near-equilibria (folds fall one way or another with the
    # jitter, which is drawn in the world frame), so it matches closely, not exactly.
    gap = np.linalg.norm(in_root[0].numpy() - alone, axis=-1)
    assert gap.mean() < 0.01 and gap.max() < 0.03
    assert alone[:, 2].min() < -0.2  # hangs below the root, not at the template's rest


def test_the_cloth_keeps_its_templates_rest_shape_not_its_start(avatar, tiny):
    """A template whose rest shape is 10% smaller than where it starts (as a fitted garment
    starts draped): the cloth pulls in to the rest lengths; without rest_vertices the
    start is the rest shape, as before, and the template without them keeps its run key."""
    import loosefit.sim.cloth as cloth
    from loosefit.sim.cloth import settle

    skirt = tiny[0]
    centre = skirt.vertices.mean(0)
    small = dataclasses.replace(skirt, rest_vertices=centre + 0.9 * (skirt.vertices - centre))
    config = ClothConfig.tiny()
    edges = np.unique(np.sort(skirt.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), 1), axis=0)
    free = ~np.isin(edges, skirt.waist).any(1)

    def lengths(v):
        return np.linalg.norm(v[edges[free, 0]] - v[edges[free, 1]], axis=1)

    rest = lengths(skirt.vertices)
    as_before = lengths(settle(avatar, skirt, config)) / rest
    shrunk = lengths(settle(avatar, small, config)) / rest
    assert np.median(as_before) > 0.97 and np.median(shrunk) < np.median(as_before) - 0.03
    body = np.zeros((3, 10, 3), np.float32)
    assert cloth._run_key(body, small, config) != cloth._run_key(body, skirt, config)
    with pytest.raises(LoosefitInputError, match=r"rest_vertices.*\(96, 3\)|rest_vertices"):
        dataclasses.replace(skirt, rest_vertices=skirt.vertices[:-1])


# -- several clips at once ------------------------------------------------------------


@pytest.fixture(scope="module")
def batch(avatar, tiny):
    """The tiny clip and a shorter sway, simulated side by side as two worlds."""
    skirt, motion, _, _ = tiny
    sway = load_motion("sway", avatar).slice(0, 4)
    done = []
    results = simulate_batch(avatar, skirt, [motion, sway], ClothConfig.tiny(), seeds=[0, 0],
                             progress=lambda d, t: done.append((d, t)))  # fmt: skip
    return sway, results, done


def test_batched_clips_match_their_own_simulations(avatar, tiny, batch):
    skirt, motion, alone, _ = tiny
    sway, (a, b), done = batch
    sway_alone = simulate(avatar, skirt, sway, ClothConfig.tiny())
    assert a.garment_vertices.shape == alone.garment_vertices.shape
    assert b.garment_vertices.shape == (sway.num_frames, skirt.num_vertices, 3)
    # The first clip's world sits where the clip would alone: the very same numbers, so the
    # other world changes nothing.
    np.testing.assert_array_equal(a.garment_vertices, alone.garment_vertices)
    np.testing.assert_array_equal(a.settled_vertices, alone.settled_vertices)
    # The second is moved metres away (Newton's self-contact ignores worlds): the same
    # physics up to float rounding there, which a swaying drape amplifies, but by less than
    # a 0.1 mm jitter of its start does (the seed).
    gap = np.linalg.norm(b.garment_vertices - sway_alone.garment_vertices, axis=-1).max()
    reseeded = simulate(avatar, skirt, sway, ClothConfig.tiny(seed=1))
    spread = np.linalg.norm(reseeded.garment_vertices - sway_alone.garment_vertices, axis=-1)
    assert gap < 0.5 * spread.max(), f"{gap * 1000:.1f} mm (seeds: {spread.max() * 1000:.1f})"
    assert b.quality["inside_max"] < 0.005
    assert abs(b.quality["strain_p99"] - sway_alone.quality["strain_p99"]) < 0.01
    # the batch steps the longer clip's timeline; the shorter one holds its last pose
    assert done[-1][1] == alone.preroll_frames + motion.num_frames - 1
    assert a.stats["batch"] == b.stats["batch"] == 2
    assert b.stats["frames_simulated"] == alone.preroll_frames + sway.num_frames - 1


def test_batched_run_resumes_and_checks_its_motions(avatar, tiny, batch, tmp_path):
    skirt, motion, _, _ = tiny
    sway, results, done = batch
    path = tmp_path / "batch.npz"
    stop = done[-1][1] - 2

    def kill(d, t):
        if d == stop:
            raise _Kill

    with pytest.raises(_Kill):
        simulate_batch(avatar, skirt, [motion, sway], ClothConfig.tiny(), progress=kill,
                       resume=path, resume_every=4, seeds=[0, 0])  # fmt: skip
    seen = []
    again = simulate_batch(
        avatar, skirt, [motion, sway], ClothConfig.tiny(), resume=path, resume_every=4,
        seeds=[0, 0], progress=lambda d, t: seen.append(d),
    )  # fmt: skip
    assert seen[0] > 1
    for got, want in zip(again, results, strict=True):
        np.testing.assert_array_equal(got.garment_vertices, want.garment_vertices)
    slow = dataclasses.replace(sway, fps=sway.fps / 2)
    with pytest.raises(LoosefitInputError, match="fps"):
        simulate_batch(avatar, skirt, [motion, slow], ClothConfig.tiny())
    with pytest.raises(LoosefitInputError, match="at least one motion"):
        simulate_batch(avatar, skirt, [], ClothConfig.tiny())


def test_the_collider_with_arms_stops_a_hand_sweeping_through_a_tiny_skirt(avatar):
    # the left arm lowered from the A-pose past hanging: the hand sweeps 18 cm inward at
    # hip height, through the skirt's side, and stops 4 cm from the hip
    from loosefit.body.rotations import axis_angle_to_matrix
    from loosefit.eval.quality import PENETRATION_TOLERANCE

    skirt = fit_skirt(avatar, TINY_SKIRT)
    n = 20
    motion = avatar.rest_motion(n)
    y = 0.3 + 0.6 * np.clip(np.arange(n) / 14, 0, 1)
    motion.rotations[:, avatar.joint_names.index("LeftArm")] = axis_angle_to_matrix(
        np.stack([np.zeros(n), y, np.zeros(n)], 1))  # fmt: skip
    body = avatar.pose_motion(motion).vertices.numpy()
    faces = avatar.faces.numpy()  # the whole body, arms and hands included

    def deepest(arms, arm_friction) -> float:
        config = dataclasses.replace(ClothConfig.tiny(), arm_collision=arms,
                                     arm_friction=arm_friction)  # fmt: skip
        g = simulate(avatar, skirt, motion, config).garment_vertices
        depth = 0.0
        for t in range(n):
            hit = closest_points(body[t], faces, g[t])
            if hit.inside.any():
                depth = max(depth, float(hit.distance[hit.inside].max()))
        return depth

    # without the arms the hand passes through the cloth
    assert deepest(False, arm_friction=None) > 0.015
    assert deepest(True, arm_friction=None) < PENETRATION_TOLERANCE  # with them it pushes it
    # the arms as a frictionless collider of their own push it as well
    assert deepest(False, arm_friction=0.0) < PENETRATION_TOLERANCE


def test_every_body_shape_is_culled_by_the_whole_motions_box(avatar):
    # the arms' own mesh too: a box left at the first frame's body would lose its contacts
    # once the dancer has moved away from where she started
    from loosefit.sim.cloth import ClothSimulator, _limb_faces

    skirt = fit_skirt(avatar, TINY_SKIRT)
    body = avatar.rest_vertices.numpy()
    faces = avatar.collider_faces(arms=False).numpy()
    config = ClothConfig.tiny()
    bounds = (body.min(0) - 5.0, body.max(0) + 5.0)
    for K in (1, 2):
        g = np.stack([skirt.vertices] * K) if K > 1 else skirt.vertices
        b = np.stack([body] * K) if K > 1 else body
        sim = ClothSimulator(g, skirt.faces, skirt.waist, b, faces, config, 1 / 30, bounds,
                             limb_faces=_limb_faces(avatar, config))  # fmt: skip
        lower = sim.model.shape_collision_aabb_lower.numpy()
        assert lower.shape == (2 * K, 3)
        want = np.repeat(bounds[0][None] + sim.offsets, 2, 0)
        np.testing.assert_allclose(lower, want, atol=1e-5)


def test_arm_friction_is_checked():
    assert ClothConfig().colliding_arms is True  # the arms as a mesh of their own
    assert ClothConfig(arm_friction=None).colliding_arms is False
    with pytest.raises(LoosefitInputError, match="arm_friction"):
        ClothConfig(arm_friction=-0.1)
    with pytest.raises(LoosefitInputError, match="arm_friction"):
        ClothConfig(arm_friction=float("nan"))
    assert ClothConfig(arm_collision="upper", arm_friction=0.0).arm_friction == 0.0


def _release(v, f, parts=None, n=1, depth=0.05):
    from loosefit.sim.cloth import TrappedRelease

    parts = np.zeros(len(v), np.int64) if parts is None else parts
    return TrappedRelease(v, (f,), parts, n, depth, 0.004)


def test_release_puts_deep_cloth_back_on_the_moving_skin():
    from tests.meshes import cube

    v, f = cube(1.0)  # centred at the origin, outward normals
    before, after = v - np.array([0.1, 0.0, 0.0]), v  # the box moved 0.1 m along +x
    x = np.array([[0.0, 0.0, 0.3], [0.0, 0.0, 0.49], [0.0, 0.0, 0.7]], np.float32)
    qd = np.ones_like(x)
    y, yd, moved = _release(after, f, n=3).step(x, qd, after, before, frame_dt=0.5)
    assert moved == 1
    # the deep one (0.2 m in), never seen outside, goes to the closest face (the top),
    # 4 mm out, with the box's velocity
    np.testing.assert_allclose(y[0], [0.0, 0.0, 0.504], atol=1e-5)
    np.testing.assert_allclose(yd[0], [0.2, 0.0, 0.0], atol=1e-5)
    # 1 cm in (within depth) and outside: untouched
    np.testing.assert_array_equal(y[1:], x[1:])
    np.testing.assert_array_equal(yd[1:], qd[1:])
    assert _release(after, f, n=3, depth=0.25).step(x, qd, after, before, 0.5)[2] == 0


def test_release_puts_cloth_back_on_the_side_it_went_in_from():
    from tests.meshes import cube

    v, f = cube(1.0)
    release = _release(v, f, n=2)
    x = np.array([[0.1, 0.0, 0.6], [0.0, 0.0, 2.0]], np.float32)  # over the top face
    qd = np.zeros_like(x)
    assert release.step(x, qd, v, v, 1 / 30)[2] == 0 and (release.face >= 0).all()
    anchors = release.face.copy()
    # the first one is pushed through to 0.4 m under the top, 0.1 m over the bottom: the
    # closest face is the bottom, but it went in at the top, where it goes back
    x[0] = [0.1, 0.0, -0.4]
    y, _, moved = release.step(x, qd, v, v, 1 / 30)
    assert moved == 1
    np.testing.assert_allclose(y[0], [0.1, 0.0, 0.504], atol=1e-5)
    np.testing.assert_array_equal(release.face, anchors)  # it was inside: anchor kept


def test_release_anchors_on_the_part_the_cloth_is_caught_in():
    from tests.meshes import cube

    a, fa = cube(1.0)  # part 0, x in [-0.5, 0.5]
    b, fb = cube(1.0)  # part 1, x in [0.7, 1.7]: 0.2 m apart
    v = np.concatenate([a, b + np.array([1.2, 0.0, 0.0])]).astype(np.float32)
    f = np.concatenate([fa, fb + len(a)])
    parts = np.repeat([0, 1], len(a))
    release = _release(v, f, parts)
    x = np.array([[0.65, 0.0, 0.0]], np.float32)  # between the two, nearer part 1
    qd = np.zeros_like(x)
    release.step(x, qd, v, v, 1 / 30)
    # pressed 0.2 m into part 0: back onto part 0 where it went in (x = 0.5), not onto
    # part 1, the closest skin when it was last outside
    x[0] = [0.3, 0.0, 0.0]
    y, _, moved = release.step(x, qd, v, v, 1 / 30)
    assert moved == 1
    np.testing.assert_allclose(y[0], [0.504, 0.0, 0.0], atol=1e-5)


def test_release_depth_is_checked():
    with pytest.raises(LoosefitInputError, match="release_depth"):
        ClothConfig(release_depth=-0.01)
    assert ClothConfig(release_depth=0.02).release_depth == 0.02
