"""Motions through the API (loosefit.api.motion): the avatar, a capture file's reading
options, its inspection, its joint map file and its sheet beside the avatar, each the same
as the library's own steps."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from loosefit.api.motion import (
    build_avatar,
    bvh_units,
    inspect_motion,
    joint_map_text,
    pose_sheet,
    retarget_config,
)
from loosefit.errors import LoosefitInputError


@pytest.fixture(scope="module")
def capture(avatar, tmp_path_factory):
    """A 12-frame spin written as a Mixamo-named BVH in centimetres."""
    from loosefit.motion.motions import load_motion
    from tests.motion.bvh_conventions import CONVENTIONS, write_convention_bvh

    motion = load_motion("spin", avatar).slice(0, 12)
    path = tmp_path_factory.mktemp("capture") / "mixamo.bvh"
    return write_convention_bvh(
        path, CONVENTIONS["mixamo"], avatar.skeleton, motion, avatar.floor_height
    )


def test_the_units_and_the_reading_options():
    from loosefit.motion.bvh import BVH_UNITS
    from loosefit.motion.retarget import RetargetConfig

    assert bvh_units() == tuple(BVH_UNITS) and "auto" in bvh_units()
    assert retarget_config() == RetargetConfig()
    config = retarget_config(units="cm", scale=0.01, joint_map="daz", smpl_up="+z")
    assert config == RetargetConfig(units="cm", scale=0.01, joint_map="daz", smpl_up="+z")
    assert not retarget_config(check_pose=False).check_pose


def test_the_avatar_of_a_shape(avatar):
    assert np.array_equal(build_avatar().rest_vertices.numpy(), avatar.rest_vertices.numpy())
    taller = build_avatar({"height": 0.9})
    assert taller.shape["height"] == 0.9 and taller.shape["weight"] == avatar.shape["weight"]
    assert taller.floor_height > avatar.floor_height + 0.05  # longer legs


def test_an_inspection_and_its_joint_map_are_the_library_s(capture):
    from loosefit.motion.inspect import inspect_motion as library
    from loosefit.motion.joint_map_files import joint_map_template

    config = retarget_config(units="cm")
    report = inspect_motion(capture, retarget=config)
    assert report.format() == library(capture, config).format()
    assert report.error is None and "units: cm" in report.format()
    text = joint_map_text(report, "mixamo.bvh")
    axes = (report.up, report.forward)
    clip = report.clip
    assert text == joint_map_template(
        clip.joint_names, report.match, "mixamo.bvh", axes, clip.parents
    )
    assert "mixamorig:LeftUpLeg" in text


def test_the_pose_sheet_is_the_library_s_drawing(capture, avatar, tmp_path):
    from PIL import Image

    from loosefit.motion.inspect import sheet_inputs
    from loosefit.motion.retarget import retarget_bvh
    from loosefit.render.skeleton_sheet import skeleton_sheet

    config = retarget_config()
    report = inspect_motion(capture, retarget=config)
    try:
        sheet = pose_sheet(report, tmp_path / "a" / "sheet.png", avatar=avatar, frames=3)
    except RuntimeError as exc:
        pytest.skip(f"no headless OpenGL (EGL) context on this machine: {exc}")
    assert sheet.pose_error is None and sheet.path == tmp_path / "a" / "sheet.png"
    # the reference: the capture at its own rate, unchecked, three frames drawn
    loose = dataclasses.replace(config, fps=None, check_pose=False, check_height=False)
    motion = retarget_bvh(report.clip, avatar.skeleton, avatar.floor_height, loose)
    inputs = sheet_inputs(report.clip, motion, loose, 3)
    body = avatar.pose_motion(inputs.motion).vertices.cpu().numpy()
    faces = avatar.faces.cpu().numpy()
    image = skeleton_sheet(inputs.points, inputs.bones, body, faces, inputs.frames)
    assert sheet.frames == inputs.frames == [0, 6, 11]
    assert np.array_equal(np.asarray(Image.open(sheet.path)), image)


def test_a_failed_pose_check_comes_back_and_the_sheet_is_still_drawn(
    capture, avatar, tmp_path, monkeypatch
):
    import loosefit.motion.pose_check

    seen = []

    def refuse(motion, skeleton, floor, source=None):
        seen.append(source)
        raise LoosefitInputError(source, "pose", "a dancer's", "a knee bent backwards")

    monkeypatch.setattr(loosefit.motion.pose_check, "check_pose", refuse)
    report = inspect_motion(capture)
    try:
        sheet = pose_sheet(report, tmp_path / "s.png", avatar=avatar, frames=2, source="my.bvh")
    except RuntimeError as exc:
        pytest.skip(f"no headless OpenGL (EGL) context on this machine: {exc}")
    assert seen == ["my.bvh"] and sheet.pose_error.found == "a knee bent backwards"
    assert sheet.path.is_file()
