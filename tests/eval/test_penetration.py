"""Where and why cloth goes deep inside the body (loosefit.eval.penetration, body_regions,
motion_signals), on a body of boxes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from loosefit.body.regions import BodyParts
from loosefit.errors import LoosefitInputError
from loosefit.eval.motion_signals import SELF_INTERSECTION_TOLERANCE, motion_signals, spin_rate
from loosefit.eval.penetration import (
    FAST_SPIN,
    diagnose_clip,
    find_events,
    find_penetrations,
    format_events,
)
from loosefit.garment.quality import quality
from loosefit.types import GarmentTemplate
from tests.meshes import cube

NAMES = ("hips", "left thigh", "right thigh", "left hand")


def boxes() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A body of four closed boxes, one region each: hips (0.4 m, at the origin), the
    thighs (0.2 m, 15 cm either side of it along x) and the left hand (0.1 m, 10 cm in
    front of the hips): vertices (32, 3), faces (48, 3), region (32,)."""
    parts = [
        (0.4, (0.0, 0.0, 0.0)),
        (0.2, (0.45, 0.0, 0.0)),
        (0.2, (-0.45, 0.0, 0.0)),
        (0.1, (0.0, -0.35, 0.0)),
    ]
    verts, faces = [], []
    for i, (size, centre) in enumerate(parts):
        v, f = cube(size)
        verts.append(v + np.asarray(centre, np.float32))
        faces.append(f + 8 * i)
    return np.concatenate(verts), np.concatenate(faces), np.repeat(np.arange(4), 8)


def static(vertices: np.ndarray, frames: int) -> np.ndarray:
    return np.repeat(vertices[None], frames, axis=0).astype(np.float32)  # (T, Vb, 3)


@pytest.fixture(scope="module")
def body():
    v, f, region = boxes()
    return v, f, region, BodyParts.build(v, f, f, region, NAMES)


def test_detector_finds_exactly_the_deep_vertices(body):
    v, f, region, parts = body
    T = 6
    g = np.tile(np.array([[0.0, 0.0, 0.5]], np.float32), (T, 5, 1))  # (T, 5, 3) above the body
    g[:, :, 0] = np.linspace(-0.2, 0.2, 5)
    g[1, 0] = [0.0, 0.0, 0.2 - 0.02]  # 2 cm inside the top of the hips
    g[2, 0] = [0.0, 0.0, 0.2 - 0.03]
    g[1, 1] = [0.05, 0.0, 0.2 - 0.003]  # 3 mm: touching, under the tolerance
    g[4, 2] = [0.45, 0.0, 0.1 - 0.04]  # 4 cm inside the top of the left thigh
    g[4, 3] = [0.0, 0.0, 0.2 - 0.01]
    g[3, 4] = np.nan  # left out
    pen = find_penetrations(g, static(v, T), parts, tolerance=0.005)
    np.testing.assert_array_equal(pen.frame, [1, 2, 4, 4])
    np.testing.assert_array_equal(pen.vertex, [0, 0, 2, 3])
    np.testing.assert_allclose(pen.depth, [0.02, 0.03, 0.04, 0.01], atol=1e-6)
    assert [NAMES[r] for r in pen.region] == ["hips", "hips", "left thigh", "hips"]
    np.testing.assert_allclose(pen.surface[2], [0.45, 0.0, 0.1], atol=1e-6)  # over it
    np.testing.assert_allclose(pen.deep_fraction, [0, 0.2, 0.2, 0, 0.4, 0])
    np.testing.assert_allclose(pen.inside_fraction, [0, 0.4, 0.2, 0, 0.4, 0])
    np.testing.assert_allclose(pen.max_depth, [0, 0.02, 0.03, 0, 0.04, 0], atol=1e-6)
    np.testing.assert_array_equal(pen.at(4), [2, 3])
    # The same shares as the data set's quality figures.
    template = GarmentTemplate(
        g[0],
        np.array([[0, 1, 2], [2, 3, 4]]),
        np.zeros((1, 2)),
        np.zeros((2, 3), np.int64),
        np.zeros(0, np.int64),
    )
    q = quality(g, template, static(v, T), f, tolerance=0.005)
    np.testing.assert_allclose(q["penetration_fraction"], pen.deep_fraction)
    with pytest.raises(LoosefitInputError):
        find_penetrations(g, static(v, T - 1), parts)


def test_events_split_on_gaps():
    flags = np.array([0, 1, 1, 0, 1, 0, 0, 1], bool)
    assert find_events(flags) == [(1, 3), (4, 5), (7, 8)]
    assert find_events(flags, merge_gap=1) == [(1, 5), (7, 8)]
    assert find_events(flags, merge_gap=2) == [(1, 8)]
    assert find_events(np.zeros(4, bool)) == []
    assert find_events(np.ones(3, bool)) == [(0, 3)]


def test_spin_rate_about_the_vertical():
    fps, omega = 30.0, 3.0
    yaw = omega * np.arange(90) / fps  # 9 rad: wraps past pi several times
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.zeros((90, 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1.0
    np.testing.assert_allclose(spin_rate(R, fps), omega, atol=1e-9)
    tilt = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])  # a bow: no turn about +Z
    np.testing.assert_allclose(spin_rate(np.stack([np.eye(3), tilt]), fps), 0.0, atol=1e-9)
    assert spin_rate(np.eye(3)[None], fps).shape == (1,)


def test_motion_signals_on_boxes(body):
    v, f, region, parts = body
    b = static(v, 3)
    b[1, 8:16, 0] -= 0.18  # the left thigh 3 cm into the hips
    b[2, 24:32, 1] += 0.1  # the left hand on the hips' front
    b[2, 16:24, 0] += 0.1  # the right thigh 5 cm from the hips
    s = motion_signals(b, np.repeat(np.eye(3)[None], 3, 0), 30.0, parts)
    assert s.limbs == ("left arm", "left leg", "right leg")  # those with regions here
    assert s.limb_collides == (True, True, True)
    np.testing.assert_allclose(s.self_depth[:, 1], [0.0, 0.03, 0.0], atol=1e-6)
    np.testing.assert_array_equal(s.self_count[:, 1], [0, 4, 0])  # the thigh's inner face
    assert NAMES[s.self_region[1, 1]] == "hips" and s.self_region[1, 2] == -1
    assert NAMES[region[s.self_vertex[1, 1]]] == "left thigh"
    assert s.self_intersecting.tolist() == [False, True, False]
    assert SELF_INTERSECTION_TOLERANCE < 0.03
    np.testing.assert_allclose(s.hand_hip[:, 0], [0.1, 0.1, 0.0], atol=1e-6)
    assert np.isinf(s.hand_hip[:, 1]).all()  # no right hand
    np.testing.assert_allclose(s.thigh_gap, [0.7, 0.52, 0.6], atol=1e-6)
    np.testing.assert_allclose(s.spin, 0.0)


def test_diagnosis_names_the_cause(body):
    v, f, region, parts = body
    T = 12
    b = static(v, T)
    b[2:6, 8:16, 0] -= 0.18  # frames 2-5: the left thigh 3 cm into the hips ...
    g = np.tile(np.array([[0.0, 0.0, 0.5]], np.float32), (T, 4, 1))
    g[3:6, 0] = [0.192, 0.085, 0.085]  # ... with cloth caught between them, 8 mm deep
    g[9:11, 1] = [0.0, 0.0, 0.17]  # frames 9-10: 3 cm inside the hips' top, during a spin
    yaw = np.zeros(T)
    yaw[7:] = 2 * FAST_SPIN * np.arange(T - 7) / 30.0
    R = np.zeros((T, 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = (
        np.cos(yaw),
        -np.sin(yaw),
        np.sin(yaw),
        np.cos(yaw),
        1.0,
    )
    diag = diagnose_clip(g, b, R, 30.0, parts, tolerance=0.005)
    first, second = diag.events
    assert (first.start, first.stop, first.worst_frame) == (3, 6, 3)
    assert first.deepest == pytest.approx(0.008, abs=1e-5) and first.region == "hips"
    assert first.self_intersecting and first.thigh_gap > 0.5
    (caught,) = first.self_intersections
    assert (caught.limb, caught.part, caught.region, caught.frame) == (
        "left leg",
        "left thigh",
        "hips",
        3,
    )
    assert caught.depth == pytest.approx(0.03, abs=1e-6) and caught.site < 0.035
    assert first.causes == [
        "self-intersecting body: the left thigh 3.0 cm inside the hips "
        "(frame 3, 3 cm from the deepest cloth)"
    ]
    assert not any("spin" in c for c in first.causes)
    assert (second.start, second.stop) == (9, 11) and second.region == "hips"
    assert second.deepest == pytest.approx(0.03, abs=1e-5) and not second.self_intersecting
    assert second.spin == pytest.approx(2 * FAST_SPIN, rel=1e-6)
    assert second.causes == [f"a fast spin ({2 * FAST_SPIN:.1f} rad/s)"]
    assert first.skin_speed == 0.0 and second.skin_speed == 0.0
    assert diag.worst_frames(3) == [9, 3, 10]  # each event's worst, then the next deepest
    table = format_events(diag.events, 0.005)
    assert "    3-5 hips" in table and "   9-10 hips" in table
    report = json.loads(json.dumps(diag.to_json()))  # JSON-safe: no inf (no right hand)
    assert report["events"][1]["causes"] == second.causes
    assert report["per_frame"]["hand_hip_m"][0][1] is None
    b[2, 8:16, 0] += 0.18  # the thigh now jumps in at frame 3: 18 cm in a 30th of a second
    first = diagnose_clip(g, b, R, 30.0, parts, tolerance=0.005).events[0]
    assert first.skin_speed == pytest.approx(5.4, rel=1e-5)
    assert first.causes[1] == "the left thigh moving fast into the cloth (5.4 m/s)"


def test_hands_that_do_not_collide_are_noted_not_blamed(body):
    v, f, region, _ = body
    collider = f[:36]  # the hand's box left out of the collider
    parts = BodyParts.build(v, f, collider, region, NAMES)
    assert not parts.collides(np.arange(24, 32)) and parts.collides(np.arange(8))
    b = static(v, 2)
    b[:, 24:32, 1] += 0.09  # the hand 1 cm from the hips' front ...
    g = np.tile(np.array([[0.0, -0.19, 0.0]], np.float32), (2, 1, 1))  # ... cloth under it
    diag = diagnose_clip(g, b, np.repeat(np.eye(3)[None], 2, 0), 30.0, parts, tolerance=0.005)
    (event,) = diag.events
    assert event.hand == "left hand" and event.hand_hip == pytest.approx(0.01, abs=1e-6)
    assert not event.hands_collide and event.causes[0].startswith("unexplained")
    assert "does not collide with the hands" in event.notes[0]
    parts = BodyParts.build(v, f, f, region, NAMES)  # now the hand collides: it presses
    diag = diagnose_clip(g, b, np.repeat(np.eye(3)[None], 2, 0), 30.0, parts, tolerance=0.005)
    assert diag.events[0].causes[0].startswith("the left hand pressing the cloth")


def test_regions_of_the_avatar(avatar):
    from loosefit.body.regions import REGIONS, body_parts

    parts = body_parts(avatar, arms=False)  # a skirt's collider: no arms
    names = [parts.names[r] for r in parts.region]
    assert set(names) == set(REGIONS) and len(names) == avatar.rest_vertices.shape[0]
    assert parts.limb_collides == {
        "left arm": False,
        "right arm": False,
        "left leg": True,
        "right leg": True,
    }
    assert not parts.collides(parts.hand_vertices[0])
    rest = avatar.rest_vertices.cpu().numpy()[None]
    s = motion_signals(rest, np.eye(3)[None], 30.0, parts)
    assert s.self_count.sum() == 0  # the rest pose does not intersect itself
    assert 0.02 < s.thigh_gap[0] < 0.05 and (s.hand_hip[0] > 0.2).all()
    assert body_parts(avatar, arms=True).limb_collides["left arm"]


def test_diagnose_command_on_a_data_set(toy_dataset, tmp_path, capsys):
    from loosefit.cli import main
    from loosefit.render.renderer import Renderer

    try:
        Renderer().close()
    except RuntimeError as exc:
        pytest.skip(f"no headless OpenGL (EGL) context: {exc}")
    out = tmp_path / "diag"
    code = main(
        [
            "diagnose",
            str(toy_dataset),
            "c",
            "--out",
            str(out),
            "--top",
            "1",
            "--size",
            "64",
            "--tolerance",
            "0.001",
        ]
    )
    assert code == 0
    printed = capsys.readouterr().out
    report = json.loads((out / "diagnosis.json").read_text())
    assert report["clip"] == "c" and report["frames"] == 16
    assert len(report["per_frame"]["deep_fraction"]) == 16
    assert f"c: {report['frames']} frames" in printed
    # The hem swung sideways by hand goes into a thigh (no motion explains it); the worst
    # event's worst frame is rendered.
    assert [e["region"] for e in report["events"]] == ["right thigh", "left thigh"]
    assert report["events"][0]["causes"][0].startswith("unexplained")
    assert report["renders"] == [str(out / "worst1_frame00014.png")]
    assert (out / "worst1_frame00014.png").is_file() and "11-15" in printed
    # A sequence file (a data set's) reads the same; a data set without a clip is refused.
    code = main(
        [
            "diagnose",
            str(toy_dataset / "sequences" / "c.npz"),
            "--out",
            str(tmp_path / "seq"),
            "--top",
            "0",
            "--tolerance",
            "0.001",
        ]
    )
    again = json.loads((tmp_path / "seq" / "diagnosis.json").read_text())
    assert code == 0 and again["per_frame"] == report["per_frame"]
    assert main(["diagnose", str(toy_dataset), "--out", str(tmp_path / "x")]) == 2
    assert "CLIP" in capsys.readouterr().err
