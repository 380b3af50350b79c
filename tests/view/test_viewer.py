"""The viewer in a headless browser: the garment is drawn and moves from frame to frame;
sequences that cannot play together are refused; a taken port gives way to the next.

The browser test needs Chromium (Debian's ``chromium``; installed with apt-get when it is
missing and the machine allows it, skipped otherwise) and draws WebGL in software.
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import time

import numpy as np
import pytest

pytest.importorskip("viser", reason="the viewer's optional extra: pip install 'loosefit[viewer]'")

from loosefit.cli import main  # noqa: E402
from loosefit.errors import LoosefitInputError  # noqa: E402
from loosefit.sequence import GarmentSequence  # noqa: E402
from loosefit.view import ViewerConfig, view  # noqa: E402
from loosefit.view.headless import BODY_BYTES, Chromium, find_chromium  # noqa: E402
from loosefit.view.scene import read_sequences  # noqa: E402


@pytest.fixture(scope="module")
def chromium_binary() -> str:
    """Chromium, installed with apt-get (Debian's package) when missing, or a skip."""
    found = find_chromium()
    if found:
        return found
    if shutil.which("apt-get") is None or os.geteuid() != 0:
        pytest.skip("no Chromium, and apt-get as root is not available to install it")
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    for cmd in (["apt-get", "update"], ["apt-get", "install", "-y", "chromium"]):
        run = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=900)
        if run.returncode != 0:
            pytest.skip(f"could not install Chromium ({' '.join(cmd)}: {run.stderr[-300:]})")
    return find_chromium() or pytest.skip("apt-get installed chromium, but it is not on PATH")


@pytest.fixture(scope="module")
def clips(toy_dataset):
    """The toy data set's clip 'a' (its hem swings) and the same clip, hem still."""
    seqs, labels, sources = read_sequences(data=toy_dataset, clip="a")
    a = seqs[0]
    still = GarmentSequence(
        a.motion,
        a.garment,
        np.repeat(a.garment_vertices[:1], a.num_frames, axis=0),
        a.avatar,
        "still",
    )
    return a, still


def _garment_mask(browser: Chromium, viewer, t: int, before: np.ndarray) -> tuple:
    """Frame ``t`` with the garment and without: the pixels it covers, and the screenshot."""
    viewer.set_frame(t)
    viewer.garments[0].visible = True
    shown = browser.settled_screenshot(before)
    viewer.garments[0].visible = False
    hidden = browser.settled_screenshot(shown)
    viewer.garments[0].visible = True
    diff = np.abs(shown.astype(np.int16) - hidden.astype(np.int16)).max(-1)  # (H, W)
    return diff > 40, shown


@pytest.mark.heavy
def test_garment_is_drawn_and_moves(clips, chromium_binary, tmp_path):
    a, _ = clips
    viewer = view([a], names=["clip a"], config=ViewerConfig(port=0, play=False, follow=False))
    try:
        assert viewer.port > 0 and viewer.url.endswith(f":{viewer.port}")
        with Chromium(chromium_binary, width=800, height=600) as browser:
            browser.open(viewer.url, panel=viewer.panel_labels)  # nothing arrives after
            first = browser.settled_screenshot()
            mask0, shot0 = _garment_mask(browser, viewer, 0, first)
            mask1, shot1 = _garment_mask(browser, viewer, 5, shot0)  # the hem swung out
        from PIL import Image

        Image.fromarray(shot0).save(tmp_path / "frame0.png")
        Image.fromarray(shot1).save(tmp_path / "frame5.png")
        n0, n1 = int(mask0.sum()), int(mask1.sum())
        assert n0 > 500 and n1 > 500, f"garment pixels: {n0}, {n1} (see {tmp_path})"
        moved = int((mask0 ^ mask1).sum())
        assert moved > 0.1 * min(n0, n1), f"{moved} of {n0} garment pixels changed ({tmp_path})"
    finally:
        viewer.close()


def test_the_panel_lists_the_controls_it_shows(clips):
    a, still = clips
    viewer = view([a], names=["clip a"], config=ViewerConfig(port=0, play=False))
    try:  # one sequence, plain: no reference to pick, no scale
        assert viewer.panel_labels == [
            "Playback",
            "Sequences",
            "Colour",
            "Play",
            "frame",
            "speed",
            "camera follows",
            "loop",
            "layout",
            "bodies",
            "clip a",
            "colour by",
        ]
    finally:
        viewer.close()
    viewer = view(
        [a, still], names=["a", "still"], config=ViewerConfig(port=0, play=True, colouring="error")
    )
    try:
        labels = viewer.panel_labels
        assert "Pause" in labels and {"a", "still", "reference", "scale max"} <= set(labels)
    finally:
        viewer.close()


@pytest.mark.heavy
def test_a_screenshot_waits_for_the_whole_panel(clips, chromium_binary, tmp_path):
    """The page loads at once and its panel arrives after, over the websocket: a screenshot
    taken once the page held still showed it empty or half built, one time in four."""
    from PIL import Image

    from loosefit.view.headless import PANEL

    a, still = clips
    viewer = view(
        [a, still], names=["a", "still"], config=ViewerConfig(port=0, play=False, colouring="error")
    )
    try:
        labels = viewer.panel_labels
        with Chromium(chromium_binary, width=1000, height=800) as browser:
            browser.open(viewer.url, settle=0.0, panel=labels)  # no time given it to settle
            assert browser.panel_missing(labels) == []
            shot = browser.settled_screenshot()
            x, y, w, h = browser.evaluate(
                f"(() => {{ const r = document.querySelector('{PANEL}').getBoundingClientRect();"
                " return [r.x, r.y, r.width, r.height]; })()"
            )
            with pytest.raises(TimeoutError, match="lacks \\['no such control'\\]"):
                browser.wait_for_panel([*labels, "no such control"], timeout=0.5)
        Image.fromarray(shot).save(tmp_path / "viewer.png")
        # the panel drawn: all three folders tall, text and the blue Play button in it
        assert h > 400, f"the panel is {h} px high ({tmp_path})"
        panel = shot[int(y) : int(y + h), int(x) : int(x + w)].astype(int)  # (h, w, 3)
        dark = (panel.max(-1) < 120).mean()  # text, outlines
        blue = ((panel[..., 2] > 180) & (panel[..., 0] < 80)).mean()
        assert dark > 0.01 and blue > 0.005, f"dark {dark:.3f}, blue {blue:.3f} ({tmp_path})"
    finally:
        viewer.close()


@pytest.mark.heavy
def test_a_fixed_pixel_ratio_sizes_the_canvas(clips, chromium_binary):
    a, _ = clips
    viewer = view([a], config=ViewerConfig(port=0, play=False, pixel_ratio=0.5))
    try:
        assert viewer.url.endswith("/?fixedDpr=0.5")
        with Chromium(chromium_binary, width=800, height=600) as browser:
            # the panel built and the canvas there: a loaded machine may take longer than
            # a second to make them
            browser.open(viewer.url, settle=1.0, panel=viewer.panel_labels)
            canvas = "document.querySelector('canvas[data-engine]')"  # three.js's
            deadline = time.monotonic() + browser.timeout
            while not browser.evaluate(f"{canvas} !== null") and time.monotonic() < deadline:
                time.sleep(0.1)
            width, css_width = browser.evaluate(f"[{canvas}.width, {canvas}.clientWidth]")
            # the headless browser's default: WebGL without multisampling (NO_ANTIALIAS)
            gl = f"{canvas}.getContext('webgl2')"
            antialias, samples = browser.evaluate(
                f"[{gl}.getContextAttributes().antialias, {gl}.getParameter({gl}.SAMPLES)]"
            )
        assert css_width > 100 and width == pytest.approx(css_width / 2, abs=1)
        assert antialias is False and samples == 0
    finally:
        viewer.close()
    with pytest.raises(LoosefitInputError, match="pixel_ratio"):
        ViewerConfig(pixel_ratio=0.0).validate(1)


@pytest.mark.heavy
def test_frames_drawn_and_new_frames_are_counted(clips, chromium_binary):
    a, _ = clips
    viewer = view([a], config=ViewerConfig(port=0, play=True, speed=0.5))
    try:
        with Chromium(chromium_binary, width=400, height=300) as browser:
            browser.open(viewer.url, settle=1.0)
            got = browser.receive(2.0)
            viewer.pause()
            time.sleep(0.5)
            still = browser.receive(1.5)
        frames = int((got.messages >= BODY_BYTES).sum())  # 15 per second sent
        assert frames > 5 and 0 < got.new_draws <= min(got.draws, frames + 1)
        assert still.new_draws == 0  # paused: whatever it drew redrew the frame shown
    finally:
        viewer.close()


def test_frames_and_colourings_through_the_api(clips):
    a, still = clips
    viewer = view(
        [a, still], names=["a", "still"], config=ViewerConfig(port=0, play=False, colouring="error")
    )
    try:
        viewer.set_frame(5)
        assert viewer.frame == 5 and int(viewer.slider.value) == 5
        # the distance to the reference: 0 for the reference itself, colour meshes shown
        assert not viewer.garments[1].visible
        assert any(m.visible for m in viewer.bin_meshes[1])
        assert "RMSE to **a**" in viewer.stats.content
        rmse = float(viewer.stats.content.split("| still | ")[1].split(" |")[0])
        d = a.garment_vertices[5] - still.garment_vertices[5]
        assert rmse == pytest.approx(100 * np.sqrt((d * d).sum(-1).mean()), abs=0.01)
        for mode in ("edge strain", "inside the body", "plain"):
            viewer.mode.value = mode
            viewer.set_frame(6)
        assert viewer.garments[0].visible
        with pytest.raises(LoosefitInputError, match="0 to 15"):
            viewer.set_frame(16)
    finally:
        viewer.close()


def test_the_floor_follows_the_bodies_in_whole_metres(clips):
    from loosefit.view.server import FLOOR_SIZE

    a, still = clips
    viewer = view([a, still], config=ViewerConfig(port=0, play=False, spacing=1.5))
    try:
        for t in (0, 8, 15):
            viewer.set_frame(t)
            x, y, _ = viewer.floor.position
            under = viewer._follow_point()  # the shown bodies' middle
            assert (x, y) == (round(under[0]), round(under[1]))  # its lines stay put
        assert viewer.floor.width == FLOOR_SIZE + 1.5  # both, side by side along x
        assert viewer.floor.height == FLOOR_SIZE
        viewer.set_visible(1, False)
        assert viewer.floor.width == FLOOR_SIZE
    finally:
        viewer.close()


def test_sequences_of_other_frame_counts_are_refused(clips, tmp_path, capsys):
    a, _ = clips
    short = GarmentSequence(a.motion.slice(0, 10), a.garment, a.garment_vertices[:10], a.avatar)
    pa, pb = a.save(tmp_path / "long.npz"), short.save(tmp_path / "short.npz")
    assert main(["view", str(pa), str(pb), "--port", "0"]) == 2
    err = capsys.readouterr().err
    assert "long.npz" in err and "short.npz" in err and "16 frames" in err and "10 frames" in err


def test_other_garments_are_refused(clips, skirt, avatar):
    from loosefit.fitting.place import carry_rigidly, fit_skirt
    from loosefit.garment.skirt import SkirtConfig

    a, _ = clips
    other = fit_skirt(avatar, SkirtConfig(style="aline", rings=5, segments=12))
    g = carry_rigidly(other, avatar.pose_motion(a.motion), avatar).numpy()
    b = GarmentSequence(a.motion, other, g, a.avatar)
    with pytest.raises(LoosefitInputError, match=r"sequence 1 and sequence 2.*another garment"):
        view([a, b], config=ViewerConfig(port=0))


def test_a_taken_port_gives_way_to_the_next(clips):
    a, _ = clips
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        viewer = view([a], config=ViewerConfig(port=port, play=False))
        try:
            assert viewer.port > port
        finally:
            viewer.close()


def test_view_command_serves_a_data_set_clip_and_prints_the_url(toy_dataset, monkeypatch, capsys):
    from loosefit.view.server import Viewer

    served = []
    monkeypatch.setattr(Viewer, "wait", lambda self: (served.append(self), self.close()))
    assert main(["view", "--data", str(toy_dataset), "--clip", "b", "--port", "0"]) == 0
    (viewer,) = served
    assert viewer.sequences[0].name == "b (simulation)" and viewer.num_frames == 16
    assert f"loosefit viewer: {viewer.url}" in capsys.readouterr().out
    assert main(["view", "--data", str(toy_dataset)]) == 2
    assert "--clip" in capsys.readouterr().err


def test_demo_view_opens_the_demo_result(tmp_path, monkeypatch, capsys, avatar):
    from loosefit.view.server import Viewer

    served = []
    monkeypatch.setattr(Viewer, "wait", lambda self: (served.append(self), self.close()))
    args = [
        "demo",
        "--out",
        str(tmp_path),
        "--motion",
        "kick",
        "--no-physics",
        "--size",
        "48",
        "--views",
        "front",
        "--max-frames",
        "6",
        "--view",
        "--port",
        "0",
    ]
    assert main(args) == 0
    (viewer,) = served
    assert viewer.num_frames == 6 and viewer.sequences[0].name == "demo (rigid)"
    assert "loosefit viewer: http://" in capsys.readouterr().out


def test_animated_garment_view_returns_the_running_viewer(clips, capsys):
    import loosefit

    a, still = clips  # a data set's clips: the API's AnimatedGarment views them
    a = loosefit.AnimatedGarment(a.motion, a.garment, a.garment_vertices, a.avatar, a.source)
    viewer = a.view(still, names=["a", "still"], wait=False, port=0, layout="overlaid")
    try:
        assert [s.name for s in viewer.sequences] == ["a", "still"]
        assert viewer.sequences[0].body is viewer.sequences[1].body  # one motion: posed once
        assert viewer.bodies[0].visible and not viewer.bodies[1].visible  # overlaid: one body
        assert viewer.url in capsys.readouterr().out
    finally:
        viewer.close()


def test_show_opens_a_data_set_s_clips_as_they_are_read(clips, capsys):
    import loosefit

    viewer = loosefit.show(*clips, wait=False, port=0)  # no conversion: any GarmentSequence
    try:
        assert len(viewer.sequences) == 2 and viewer.url in capsys.readouterr().out
    finally:
        viewer.close()
