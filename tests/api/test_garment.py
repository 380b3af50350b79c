"""Garments through the API (loosefit.api.garment): a garment file placed on the avatar or
fitted to it, written, pictured; a garment carried by the body, kept as a sequence and
exported with it; each against the library's own functions called directly."""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.api.garment import (
    carry_rigidly,
    dressed_sequence,
    fit_config,
    fit_preview,
    garment_from_file,
    save_garment,
)
from loosefit.errors import LoosefitInputError


@pytest.fixture(scope="module")
def skirt_file(skirt, tmp_path_factory):
    """The coarse skirt of the tests as a file, in centimetres, Y up."""
    from loosefit.garment.obj import write_obj

    v = skirt.vertices.astype(np.float64) * 100.0
    path = tmp_path_factory.mktemp("garment") / "mine.obj"
    write_obj(path, np.stack([v[:, 0], v[:, 2], -v[:, 1]], 1), skirt.faces)
    return path


@pytest.fixture(scope="module")
def motion(avatar):
    from loosefit.motion.motions import load_motion

    return load_motion("spin", avatar).slice(10, 16)


def test_a_placed_file_is_the_import_s(skirt_file, avatar):
    from loosefit.fitting.place import import_garment

    placed = garment_from_file(skirt_file, avatar, offset=(0.0, 0.0, 0.01), attach="top")
    offset = (0.0, 0.0, 0.01)
    template, report = import_garment(skirt_file, avatar, None, None, None, offset, attach="top")
    np.testing.assert_array_equal(placed.template.vertices, template.vertices)
    np.testing.assert_array_equal(placed.template.waist, template.waist)
    assert placed.report == report and report["units"]["value"] == "cm"
    assert placed.fit is None and placed.avatar is avatar
    with pytest.raises(LoosefitInputError, match="units"):
        garment_from_file(skirt_file, avatar, units="furlong")


def test_a_fitted_file_is_the_fit_s(skirt_file, avatar, capsys):
    from loosefit.fitting.drape import FitConfig, fit_garment

    config = fit_config(settle_seconds=0.0)
    assert config == FitConfig(settle_seconds=0.0)
    fitted = garment_from_file(skirt_file, avatar, fit=config, kind="skirt", bars=True)
    by_hand = FitConfig(settle_seconds=0.0)
    direct = fit_garment(skirt_file, None, by_hand, kind="skirt", avatar=avatar)
    np.testing.assert_array_equal(fitted.template.vertices, direct.template.vertices)
    assert fitted.report == direct.template.meta["import"] == fitted.template.meta["import"]
    assert fitted.fit.inside_after == direct.report.inside_after == 0
    assert fitted.avatar is avatar
    assert "fit: place" in capsys.readouterr().err  # a bar per stage
    with pytest.raises(LoosefitInputError, match="settle_seconds"):
        fit_config(settle_seconds=-1.0)


def test_a_saved_garment_is_its_obj_and_template(skirt, tmp_path):
    from loosefit.garment.obj import write_obj
    from loosefit.types import GarmentTemplate

    obj, npz = save_garment(skirt, tmp_path / "new" / "folder", "mine")
    assert (obj, npz) == (tmp_path / "new/folder/mine.obj", tmp_path / "new/folder/mine.npz")
    write_obj(tmp_path / "direct.obj", skirt.vertices, skirt.faces, skirt.uvs, skirt.face_uvs)
    assert obj.read_bytes() == (tmp_path / "direct.obj").read_bytes()
    back = GarmentTemplate.load(npz)
    np.testing.assert_array_equal(back.vertices, skirt.vertices)
    np.testing.assert_array_equal(back.waist, skirt.waist)
    assert save_garment(skirt, tmp_path)[0] == tmp_path / f"{skirt.name}.obj"  # its own name


def test_the_preview_is_the_renderer_s_still(skirt, avatar, tmp_path):
    from loosefit.fitting.drape import FitReport
    from loosefit.render.clip import render_still
    from loosefit.render.renderer import RenderConfig, RenderMesh

    fit = FitReport(3, 0.01, 0.02, 0.01, 0.03, 0.01, 0, 0.0)
    try:
        image = fit_preview(tmp_path / "p.png", skirt, fit, avatar, size=64)
    except RuntimeError as exc:
        pytest.skip(f"no headless OpenGL (EGL) context on this machine: {exc}")
    up = np.array([0.0, 0.0, avatar.floor_height], np.float32)
    scene = [
        RenderMesh(
            avatar.faces.numpy(), avatar.rest_vertices.float().numpy() + up, "body", name="body"
        ),
        RenderMesh(skirt.faces, skirt.vertices + up, "garment", name=skirt.name),
    ]
    title = f"{skirt.name} fitted: 0 of {skirt.num_vertices} vertices inside the body, "
    config = RenderConfig(width=64, height=64, views=("front", "side"), frame_counter=False)
    direct = render_still(scene, tmp_path / "d.png", config, title + "moved by at most 3.0 cm")
    assert image.shape == (64, 128, 3) and (tmp_path / "p.png").is_file()
    np.testing.assert_array_equal(image, direct)


def test_a_garment_carried_rigidly_is_the_placement_s(skirt, avatar, motion):
    from loosefit.fitting.place import carry_rigidly as direct

    body = avatar.pose_motion(motion)
    carried = carry_rigidly(skirt, body, avatar)
    assert isinstance(carried, np.ndarray) and carried.shape == (6, skirt.num_vertices, 3)
    np.testing.assert_array_equal(carried, direct(skirt, body, avatar).numpy())
    np.testing.assert_array_equal(
        carry_rigidly(skirt, body, avatar, joint="Spine"),
        direct(skirt, body, avatar, "Spine").numpy(),
    )


def test_a_dressed_sequence_records_the_avatar_and_saves(skirt, avatar, motion, tmp_path):
    from loosefit.api import AnimatedGarment
    from loosefit.sequence import GarmentSequence

    garment = np.repeat(skirt.vertices[None], motion.num_frames, 0)
    seq = dressed_sequence(motion, skirt, garment, avatar, "rigid")
    assert isinstance(seq, AnimatedGarment) and seq.source == "rigid"
    assert seq.avatar == {"rig": avatar.config.rig, "shape": avatar.shape}
    back = GarmentSequence.load(seq.save(tmp_path / "s.npz"))
    np.testing.assert_array_equal(back.garment_vertices, garment)
    assert back.avatar == seq.avatar and back.name == motion.name


def test_a_dressed_sequence_exports_with_the_body_its_caller_posed(
    skirt, avatar, motion, tmp_path, monkeypatch
):
    import loosefit.body.avatar
    from loosefit.export import body_skin, export_animation, garment_and_body

    body = avatar.pose_motion(motion)
    garment = carry_rigidly(skirt, body, avatar)
    seq = dressed_sequence(motion, skirt, garment, avatar, "rigid", body=body)

    def no_new_avatar(*_args, **_kwargs):
        raise AssertionError("the avatar was built again")

    monkeypatch.setattr(loosefit.body.avatar, "Avatar", no_new_avatar)
    written = seq.export(tmp_path / "ours.pc2")
    meshes = garment_and_body(
        skirt, garment, body.vertices.numpy(), avatar.faces.numpy(), body_skin(avatar, body)
    )
    direct = export_animation(tmp_path / "direct.pc2", meshes, 30.0)
    assert written[0] == tmp_path / "ours.pc2" and len(direct) == len(written)
    for ours, theirs in zip(written, direct, strict=True):
        assert ours.read_bytes() == theirs.read_bytes(), ours
    assert seq.export(tmp_path / "ours.usda")[0].is_file()
    with pytest.raises(LoosefitInputError, match="suffix"):
        seq.export(tmp_path / "x.fbx")
