"""The viewer's scene and panel, served on a free port and driven from here (no browser)."""

import numpy as np
import pytest

pytest.importorskip("viser", reason="the viewer's optional extra: pip install 'loosefit[viewer]'")

from loosefit.errors import LoosefitInputError  # noqa: E402
from loosefit.types import GarmentTemplate  # noqa: E402
from loosefit.view.config import ViewerConfig  # noqa: E402
from loosefit.view.scene import ViewSequence  # noqa: E402
from loosefit.view.server import FLOOR_SIZE, Viewer  # noqa: E402
from tests.meshes import cube, grid  # noqa: E402

T = 5


def _sequences(shift=0.01, walk=(0.3, 0.0, 0.0)):
    """Two sequences of one sheet over one box body walking along ``walk`` a frame, the
    second's sheet ``shift`` m off the first's along x."""
    v, f = grid(3, -0.2, 0.2, z=1.0)
    template = GarmentTemplate(v, f, (v[:, :2] + 0.2) / 0.4, f.copy(), np.arange(3), name="sheet")
    step = np.arange(T, dtype=np.float32)[:, None, None] * np.float32(walk)
    garment = v[None] + step  # (T, 9, 3)
    bv, bf = cube(0.3)
    body = (bv + np.float32([0.0, 0.0, 0.65]))[None] + step  # (T, 8, 3), on the floor at 0.5
    seqs = [
        ViewSequence("a", "a.npz", garment, template, body, bf, 10.0),
        ViewSequence("b", "b.npz", garment + np.float32([shift, 0, 0]), template, body, bf, 10.0),
    ]
    return seqs


@pytest.fixture
def viewer(request):
    config = getattr(request, "param", {})
    v = Viewer(_sequences(), ViewerConfig(port=0, play=False, follow=False, **config))
    yield v
    v.close()


def test_sequences_stand_side_by_side_and_the_frame_shows_on_both(viewer):
    assert viewer.url == f"http://localhost:{viewer.port}" and viewer.num_frames == T
    np.testing.assert_allclose([n.position for n in viewer.nodes], [[-0.5, 0, 0], [0.5, 0, 0]])
    assert viewer.floor.width == FLOOR_SIZE + 1.0
    viewer.set_frame(3)
    assert viewer.frame == 3 and int(viewer.slider.value) == 3
    for i, seq in enumerate(viewer.sequences):
        np.testing.assert_allclose(viewer.garments[i].vertices, seq.garment[3])
        np.testing.assert_allclose(viewer.bodies[i].vertices, seq.body[3])
    assert "frame **3** of 5 · 0.30 s of 0.50 s · 10 fps" == viewer.time_text.content
    assert "| b | 1.00 |" in viewer.stats.content  # 1 cm from the reference, a


def test_the_floor_stays_under_the_walk_in_whole_metres(viewer):
    positions = []
    for t in range(T):
        viewer.set_frame(t)
        positions.append(tuple(viewer.floor.position))
    # the bodies' middle walks 0.3 m a frame from x = 0: the floor steps by whole metres
    assert [p[0] for p in positions] == [0.0, 0.0, 1.0, 1.0, 1.0]
    assert all(p[2] == pytest.approx(0.5) for p in positions)  # the lowest body point


@pytest.mark.parametrize("viewer", [{"layout": "overlaid"}], indirect=True)
def test_overlaid_sequences_of_one_body_show_it_once(viewer):
    np.testing.assert_allclose([n.position for n in viewer.nodes], [[0, 0, 0], [0, 0, 0]])
    assert [b.visible for b in viewer.bodies] == [True, False]
    assert not any(label.visible for label in viewer.labels)


def test_a_hidden_sequence_leaves_the_other_centred(viewer):
    viewer.set_visible(0, False)
    assert not viewer.nodes[0].visible and viewer.seq_boxes[0].value is False
    np.testing.assert_allclose(viewer.nodes[1].position, [0, 0, 0])
    assert viewer.bodies[1].visible and not viewer.bodies[0].visible


@pytest.mark.parametrize("viewer", [{"colouring": "error"}], indirect=True)
def test_a_colouring_draws_each_garment_in_bins(viewer):
    viewer.set_frame(1)
    assert not any(g.visible for g in viewer.garments)
    assert viewer.scale_max.visible and viewer.colour_bar.visible
    # b is 1 cm from a everywhere: one bin holds all its faces; a is 0 from itself
    for i in range(2):
        shown = [m for m in viewer.bin_meshes[i] if m.visible]
        assert len(shown) == 1
        assert len(shown[0].faces) == len(viewer.sequences[i].template.faces)
    bins = viewer.bin_meshes
    assert next(k for k, m in enumerate(bins[0]) if m.visible) == 0
    assert next(k for k, m in enumerate(bins[1]) if m.visible) > 0
    assert viewer.panel_labels[:3] == ["Playback", "Sequences", "Colour"]
    assert "scale max" in viewer.panel_labels


def test_a_frame_out_of_range_and_a_bad_config_are_refused(viewer):
    with pytest.raises(LoosefitInputError, match="'t': expected 0 to 4, found 5"):
        viewer.set_frame(5)
    with pytest.raises(LoosefitInputError, match="'reference'"):
        Viewer(_sequences(), ViewerConfig(port=0, reference=2))


def test_play_and_pause_label_the_button(viewer):
    viewer.play()
    assert viewer.playing and viewer.play_button.label == "Pause"
    viewer.pause()
    assert not viewer.playing and viewer.play_button.label == "Play"
