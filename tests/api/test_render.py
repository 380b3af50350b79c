"""Rendering through the API (loosefit.api.render): the garment placed, a stored clip read,
and a scene's frames the same pixels as the renderer's own."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from loosefit.api.render import (
    garment_template,
    read_stored_clip,
    render_clip,
    render_garments,
)
from loosefit.errors import LoosefitInputError


@pytest.fixture(scope="module")
def spin(avatar):
    from loosefit.motion.motions import load_motion

    return load_motion("spin", avatar).slice(0, 2)


def _frames(folder):
    return [np.asarray(Image.open(p)) for p in sorted((folder / "frames").glob("*.png"))]


def test_a_garment_is_placed_on_the_avatar(avatar):
    from loosefit.fitting.place import garment_for

    skirt = garment_template("flared", avatar=avatar)
    assert np.array_equal(skirt.vertices, garment_for("flared", avatar).vertices)
    assert garment_template("none", avatar=avatar) is None
    with pytest.raises(LoosefitInputError, match="ballgown"):
        garment_template("ballgown", avatar=avatar)


def test_a_stored_clip_is_a_sequence_file_or_a_data_set_s_clip(toy_dataset):
    from loosefit.data.format import DatasetReader

    reader = DatasetReader(toy_dataset)
    first = read_stored_clip(dataset=toy_dataset)
    assert first.label == f"{toy_dataset.name}/a"
    b = read_stored_clip(dataset=toy_dataset, clip="b")
    assert b.label == f"{toy_dataset.name}/b"
    assert np.array_equal(b.sequence.garment_vertices, reader.read("b").garment_vertices)
    path = toy_dataset / "sequences" / "c.npz"
    c = read_stored_clip(sequence=path)
    assert c.label == "c" and c.sequence.source == "toy"
    assert np.array_equal(c.sequence.motion.rotations, reader.read("c").motion.rotations)
    with pytest.raises(LoosefitInputError, match="sequence or dataset"):
        read_stored_clip()


def test_a_render_is_the_renderer_s_own(avatar, spin, tmp_path):
    from loosefit.api.garment import carry_rigidly
    from loosefit.render.clip import render_clip as library
    from loosefit.render.renderer import RenderConfig, RenderMesh

    skirt = garment_template("aline", avatar=avatar)
    body = avatar.pose_motion(spin)
    garment = carry_rigidly(skirt, body, avatar)
    ours, theirs = tmp_path / "ours", tmp_path / "theirs"
    ours.mkdir(), theirs.mkdir()
    try:
        result = render_clip(
            ours,
            avatar=avatar,
            motion=spin,
            title="spin",
            template=skirt,
            garment=garment,
            size=48,
            views=["front", "side"],
            follow=False,
            png_every=1,
        )
    except RuntimeError as exc:
        pytest.skip(f"no headless OpenGL (EGL) context on this machine: {exc}")
    scene = [
        RenderMesh(avatar.faces.numpy(), body.vertices.numpy(), "body", name="body"),
        RenderMesh(skirt.faces, garment, "garment", name=skirt.name),
    ]
    config = RenderConfig(width=48, height=48, views=("front", "side"), follow=False)
    library(scene, theirs, fps=spin.fps, config=config, title="spin", png_every=1)
    assert result.video == ours / "video.mp4" and result.video.is_file()
    mine, reference = _frames(ours), _frames(theirs)
    assert len(mine) == 2
    assert all(np.array_equal(a, b) for a, b in zip(mine, reference, strict=True))
    # the body alone, posed here: the same body as the one passed in
    alone = tmp_path / "alone"
    alone.mkdir()
    render_clip(alone, avatar=avatar, motion=spin, title="spin", size=48, png_every=1)
    assert len(_frames(alone)) == 2


def test_garments_alone_are_the_renderer_s_own(skirt, tmp_path):
    from loosefit.render.clip import render_clip as library
    from loosefit.render.renderer import RenderConfig, RenderMesh

    vertices = np.stack([skirt.vertices, skirt.vertices + [0.0, 0.0, 0.1]]).astype(np.float32)
    ours, theirs = tmp_path / "ours", tmp_path / "theirs"
    ours.mkdir(), theirs.mkdir()
    try:
        render_garments(ours, faces=skirt.faces, vertices=vertices, title="two", size=40)
    except RuntimeError as exc:
        pytest.skip(f"no headless OpenGL (EGL) context on this machine: {exc}")
    scene = [RenderMesh(skirt.faces, vertices, "garment", name="garment")]
    config = RenderConfig(width=40, height=40, views=("front", "side"), follow=False)
    library(scene, theirs, fps=4.0, config=config, png_every=1, title="two")
    mine, reference = _frames(ours), _frames(theirs)
    assert len(mine) == 2
    assert all(np.array_equal(a, b) for a, b in zip(mine, reference, strict=True))
