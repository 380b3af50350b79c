"""Driving the simulator through clips (loosefit.sim.driver): a tiny skirt on a short motion,
one clip or several at once, killed and resumed, and the drape alone.

The first run ever compiles Newton's and Warp's CPU kernels (a minute or so,
cached under ~/.cache/warp); after that the whole file takes well under a minute.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.fitting.place import fit_skirt
from loosefit.garment.skirt import SkirtConfig
from loosefit.geometry.query import closest_points
from loosefit.motion.chain import place_motion, preroll
from loosefit.motion.motions import load_motion
from loosefit.sim.cloth_config import ClothConfig
from loosefit.sim.driver import SimulationError, _guard, settle, simulate, simulate_batch
from loosefit.sim.resume import run_key
from loosefit.types import GarmentTemplate, Motion
from tests.sim.spread import mean_gap, seed_bound

TINY_SKIRT = SkirtConfig(style="aline", rings=8, segments=24)


def facing_x(motion: Motion) -> Motion:
    """``motion`` turned about its first root position to start facing +X: a quarter turn
    of the rest pose is exact in floats, so the drape settled there is the drape settled
    at the origin (:func:`settle`) but for the jitter, drawn in the world frame. At the
    spin's own 4 degrees the processor's rounding decides the folds: a clip started from
    settle()'s drape was 13.9 mm from it with one processor's kernels, 7.2 with another's
    (docs/design/TEST_TOLERANCES.md)."""
    forward = motion.rotations[0, 0] @ np.array([0.0, -1.0, 0.0])
    heading = math.atan2(forward[0], -forward[1])
    return place_motion(motion, math.pi / 2 - heading, motion.root_translation[0, :2])


@pytest.fixture(scope="module")
def tiny(avatar):
    """A coarse skirt, six frames of a spin ramping up (turned to start facing +X), and its
    simulation."""
    skirt = fit_skirt(avatar, TINY_SKIRT)
    motion = facing_x(load_motion("spin", avatar).slice(20, 26))
    done = []
    result = simulate(
        avatar, skirt, motion, ClothConfig.tiny(), progress=lambda d, t: done.append((d, t))
    )
    return skirt, motion, result, done


@pytest.fixture(scope="module")
def seed_spread(avatar, tiny) -> float:
    """How far (m, mean over vertices and frames) the tiny clip's cloth moves when its start
    jitter is drawn with another seed: the larger of two seeds, this run, this machine."""
    skirt, motion, result, _ = tiny
    return max(
        mean_gap(
            simulate(avatar, skirt, motion, ClothConfig.tiny(seed=s)).garment_vertices,
            result.garment_vertices,
        )
        for s in (1, 2)
    )


def test_tiny_skirt_stays_finite_attached_and_outside(avatar, tiny):
    skirt, motion, result, done = tiny
    g = result.garment_vertices
    assert g.shape == (motion.num_frames, skirt.num_vertices, 3) and g.dtype == np.float32
    assert np.isfinite(g).all()
    body = avatar.pose_motion(motion).vertices.numpy()
    faces = avatar.faces.numpy()
    # the quality gate's bounds, not the cloth's positions: the waistband is glued 3 mm out,
    # the contact keeps the cloth 4 mm out (the same on every target: TEST_TOLERANCES.md)
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
    assert result.quality["strain_p99"] < 0.1  # the quality gate's figure (0.044 here)


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


def test_a_fast_body_at_the_skirt_gets_more_substeps(avatar, tiny):
    # The spin's legs and hips move more than 5 mm a frame: at 0.5 mm a substep (a limit no
    # waistband reaches here, at 1 m a substep) those frames need more than 8; the arms,
    # above the waistband, do not count. Accelerated iterations ride along.
    skirt, motion, result, _ = tiny
    config = ClothConfig.tiny(
        max_substeps=16, substep_waist_move=1.0, substep_body_move=0.0005, chebyshev_rho=0.9
    )
    legs = simulate(avatar, skirt, motion, config)
    assert 8 < legs.stats["substeps_max"] <= 16
    assert np.isfinite(legs.garment_vertices).all() and legs.quality["inside_max"] < 0.005
    waist_only = simulate(
        avatar, skirt, motion, dataclasses.replace(config, substep_body_move=None)
    )
    assert waist_only.stats["substeps_max"] == 8
    with pytest.raises(LoosefitInputError, match="substep_body_move"):
        ClothConfig(substep_body_move=0.0)


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
        simulate(
            avatar, skirt, motion, ClothConfig.tiny(), progress=kill, resume=path, resume_every=4
        )
    assert path.is_file()
    seen = []
    again = simulate(
        avatar,
        skirt,
        motion,
        ClothConfig.tiny(),
        progress=lambda d, t: seen.append(d),
        resume=path,
        resume_every=4,
    )
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
        simulate(
            avatar, skirt, motion, ClothConfig.tiny(), progress=kill, resume=path, resume_every=4
        )
    seen = []
    again = simulate(
        avatar,
        skirt,
        motion,
        ClothConfig.tiny(release_depth=0.01),
        resume=path,
        resume_every=4,
        progress=lambda d, t: seen.append(d),
    )
    assert seen[0] > 1  # nothing was ever 1 cm inside: the saved frames are the same run's
    np.testing.assert_array_equal(again.garment_vertices, result.garment_vertices)
    assert again.stats["released_frames"] == 0


def test_resume_ignores_the_state_of_another_run(avatar, tiny, tmp_path):
    skirt, motion, result, done = tiny
    path = tmp_path / "run.npz"
    np.savez(path, key=np.array("another run"), frame=np.int64(3))
    seen = []
    again = simulate(
        avatar, skirt, motion, ClothConfig.tiny(), resume=path, progress=lambda d, t: seen.append(d)
    )
    assert seen[0] == 1
    np.testing.assert_array_equal(again.garment_vertices, result.garment_vertices)


def test_settle_alone_gives_the_drape_every_clip_starts_from(avatar, tiny):
    from loosefit.model.motion_features import root_frames

    skirt, motion, result, _ = tiny
    alone = settle(avatar, skirt, ClothConfig.tiny(), fps=motion.fps)
    # simulate() settles standing where the motion starts, turned to its heading.
    c = ClothConfig.tiny()
    rot, root, _ = preroll(motion, avatar.floor_height, c.settle_seconds, c.blend_seconds)
    import torch

    H, p = root_frames(torch.from_numpy(rot[:1]), torch.from_numpy(root[:1]))
    in_root = (torch.from_numpy(result.settled_vertices)[None] - p[:, None]) @ H
    # The clip settled facing +X, settle() at the origin facing -Y: the same drape but for
    # the jitter's pattern (drawn in the world frame), so the two agree as the drapes of two
    # seeds do (3x the settle's seed spread measured here, floor 3 mm: bench/
    # test_tolerances.py). A drape left in the world frame, or not turned back, is
    # centimetres off.
    reseeded = settle(avatar, skirt, ClothConfig.tiny(seed=1), fps=motion.fps)
    gap, spread = mean_gap(in_root[0].numpy(), alone), mean_gap(reseeded, alone)
    assert gap < max(3 * spread, 0.003), f"{gap * 1000:.2f} mm (seeds: {spread * 1000:.2f})"
    assert alone[:, 2].min() < -0.2  # hangs below the root, not at the template's rest


def test_settled_once_every_clip_starts_from_the_one_drape(avatar, tiny, seed_spread):
    """``settle_once``: the batch's clips skip their settle phase and start from one drape,
    placed where each motion starts; the cloth that follows is the clip's cloth (within what
    another jitter seed changes: it starts from the drape at rest, jittered again)."""
    from loosefit.model.motion_features import root_frames

    skirt, motion, result, _ = tiny
    once = ClothConfig.tiny(settle_once=True)
    drape = settle(avatar, skirt, ClothConfig.tiny(), fps=motion.fps)
    (given,) = simulate_batch(avatar, skirt, [motion], once, drape=drape)
    n_blend = round(once.blend_seconds * motion.fps)
    assert given.preroll_frames == 1 + n_blend < result.preroll_frames  # no settle frames
    c = ClothConfig.tiny()
    rot, root, _ = preroll(motion, avatar.floor_height, c.settle_seconds, c.blend_seconds)
    import torch

    H, p = root_frames(torch.from_numpy(rot[:1]), torch.from_numpy(root[:1]))
    start = ((torch.from_numpy(given.settled_vertices)[None] - p[:, None]) @ H)[0].numpy()
    off = np.linalg.norm(start - drape, axis=-1)  # the drape, placed (and jittered); the
    assert np.median(off) < 1e-3 and off.max() < 5e-3  # waistband glued to the body
    gap = mean_gap(given.garment_vertices, result.garment_vertices)
    bound = seed_bound(seed_spread)  # tests/sim/spread.py
    assert gap < bound, (
        f"{gap * 1000:.1f} mm from the clip settled on its own, {bound * 1000:.1f} mm allowed"
        f" (seeds: {seed_spread * 1000:.1f} mm)"
    )
    assert given.quality["inside_max"] < 0.005
    (settled_here,) = simulate_batch(avatar, skirt, [motion], once)  # settled once, here
    np.testing.assert_array_equal(settled_here.garment_vertices, given.garment_vertices)
    with pytest.raises(LoosefitInputError, match=r"drape.*finite numbers"):
        simulate_batch(avatar, skirt, [motion], once, drape=drape[:-1])


def test_one_self_contact_pass_a_substep(avatar, tiny, seed_spread):
    skirt, motion, result, _ = tiny
    one = simulate(avatar, skirt, motion, ClothConfig.tiny(self_contact_passes=1))
    gap = np.linalg.norm(one.garment_vertices - result.garment_vertices, axis=-1)
    # another schedule, the same cloth: it moves the cloth less than another jitter seed
    # does (measured here; hundreds of times less on every target in bench/data/test_tolerances.py)
    assert 0 < gap.max() and gap.mean() < seed_spread
    assert one.quality["inside_max"] < 0.005
    with pytest.raises(LoosefitInputError, match="self_contact_passes"):
        ClothConfig(self_contact_passes=3)


def test_the_cloth_keeps_its_templates_rest_shape_not_its_start(avatar, tiny):
    """A template whose rest shape is 10% smaller than where it starts (as a fitted garment
    starts draped): the cloth pulls in to the rest lengths; without rest_vertices the
    start is the rest shape, as before, and the template without them keeps its run key."""

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
    assert run_key(body, small, config) != run_key(body, skirt, config)
    with pytest.raises(LoosefitInputError, match=r"rest_vertices.*\(96, 3\)|rest_vertices"):
        dataclasses.replace(skirt, rest_vertices=skirt.vertices[:-1])


@pytest.fixture(scope="module")
def batch(avatar, tiny):
    """The tiny clip and a shorter sway, simulated side by side as two worlds."""
    skirt, motion, _, _ = tiny
    sway = load_motion("sway", avatar).slice(0, 4)
    done = []
    results = simulate_batch(
        avatar,
        skirt,
        [motion, sway],
        ClothConfig.tiny(),
        seeds=[0, 0],
        progress=lambda d, t: done.append((d, t)),
    )
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
    # physics up to float rounding there, which a swaying drape amplifies as it does a 0.1 mm
    # jitter of its start: within the seeds' spread measured here (tests/sim/spread.py).
    gap = mean_gap(b.garment_vertices, sway_alone.garment_vertices)
    reseeded = simulate(avatar, skirt, sway, ClothConfig.tiny(seed=1))
    spread = mean_gap(reseeded.garment_vertices, sway_alone.garment_vertices)
    bound = seed_bound(spread)
    assert gap < bound, (
        f"{gap * 1000:.1f} mm, {bound * 1000:.1f} allowed (seed: {spread * 1000:.1f})"
    )
    # the quality gate's figures: no vertex 5 mm inside; strain p99 within 0.01, ten times
    # its spread over seeds and CPU targets (docs/design/TEST_TOLERANCES.md)
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
        simulate_batch(
            avatar,
            skirt,
            [motion, sway],
            ClothConfig.tiny(),
            progress=kill,
            resume=path,
            resume_every=4,
            seeds=[0, 0],
        )
    seen = []
    again = simulate_batch(
        avatar,
        skirt,
        [motion, sway],
        ClothConfig.tiny(),
        resume=path,
        resume_every=4,
        seeds=[0, 0],
        progress=lambda d, t: seen.append(d),
    )
    assert seen[0] > 1
    for got, want in zip(again, results, strict=True):
        np.testing.assert_array_equal(got.garment_vertices, want.garment_vertices)
    slow = dataclasses.replace(sway, fps=sway.fps / 2)
    with pytest.raises(LoosefitInputError, match="fps"):
        simulate_batch(avatar, skirt, [motion, slow], ClothConfig.tiny())
    with pytest.raises(LoosefitInputError, match="at least one motion"):
        simulate_batch(avatar, skirt, [], ClothConfig.tiny())


@pytest.mark.heavy
def test_the_collider_with_arms_stops_a_hand_sweeping_through_a_tiny_skirt(avatar):
    # the left arm lowered from the A-pose past hanging: the hand sweeps 18 cm inward at
    # hip height, through the skirt's side, and stops 4 cm from the hip
    from loosefit.garment.quality import PENETRATION_TOLERANCE
    from loosefit.geometry.rotations import axis_angle_to_matrix

    skirt = fit_skirt(avatar, TINY_SKIRT)
    n = 20
    motion = avatar.rest_motion(n)
    y = 0.3 + 0.6 * np.clip(np.arange(n) / 14, 0, 1)
    motion.rotations[:, avatar.joint_names.index("LeftArm")] = axis_angle_to_matrix(
        np.stack([np.zeros(n), y, np.zeros(n)], 1)
    )
    body = avatar.pose_motion(motion).vertices.numpy()
    faces = avatar.faces.numpy()  # the whole body, arms and hands included

    def deepest(arms, arm_friction) -> float:
        config = dataclasses.replace(
            ClothConfig.tiny(), arm_collision=arms, arm_friction=arm_friction
        )
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
