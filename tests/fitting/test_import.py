"""A user's garment file onto the avatar: units, axes, placement, attachment, bad files.

(``loosefit.fitting.place``'s placement and import; ``loosefit.garment.importer``'s reading and
guesses are exercised through it.)
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.fitting.place import (
    STRAP_CLEARANCE,
    check_clear_of_body,
    chest_height,
    fit_dress,
    import_garment,
    natural_waist_height,
)
from loosefit.garment.dress import DressConfig
from loosefit.garment.importer import UNITS, detect_units, read_garment_mesh
from loosefit.garment.mesh_checks import boundary_loops, nonmanifold_edges
from loosefit.garment.obj import write_obj


@pytest.fixture(scope="module")
def dresses(avatar):
    """The parametric dress, with straps and strapless, at the CPU resolution."""
    return {s: fit_dress(avatar, DressConfig.preset("cpu", s)) for s in ("straps", "strapless")}


def _export(template, path: Path, unit: str, up: str, shift=(0.0, 0.0, 0.0)) -> Path:
    """The garment written as another tool would: in ``unit``, with ``up`` up, moved."""
    v = (template.vertices.astype(np.float64) + shift) / UNITS[unit]
    if up == "y":  # (x, y, z) Z up -> (x, z, -y) Y up, the avatar's front (-Y) to +Z
        v = np.stack([v[:, 0], v[:, 2], -v[:, 1]], 1)
    write_obj(path, v.astype(np.float32), template.faces, template.uvs, template.face_uvs)
    return path


@pytest.mark.parametrize("style", ["straps", "strapless"])
def test_a_dress_in_centimetres_with_y_up_lands_where_the_parametric_one_is(
    dresses, avatar, tmp_path, style
):
    dress = dresses[style]
    path = _export(dress, tmp_path / "dress.obj", "cm", "y", shift=(0.4, -1.2, 0.9))
    kind = None if style == "straps" else "dress"  # a strapless dress looks like a skirt
    placed, report = import_garment(path, avatar, kind=kind)
    assert report["units"] == {
        "value": "cm",
        "guessed": True,
        **{k: report["units"][k] for k in ("height_m", "width_m")},
    }
    assert report["up"] == {"value": "y", "guessed": True}
    assert report["kind"]["value"] == "dress"
    err = np.abs(placed.vertices - dress.vertices).max()
    assert err < 1e-3, f"{style}: {1000 * err:.2f} mm from the parametric dress"
    assert np.array_equal(placed.faces, dress.faces)
    assert report["uv_source"] == "file"  # the file's UVs are kept
    # the same vertices hold it: the top band, or the straps over the shoulders
    assert placed.meta["attachment"] == dress.meta["attachment"]
    if style == "strapless":
        assert set(placed.waist.tolist()) == set(dress.waist.tolist())
    else:
        top = placed.vertices[placed.waist, 2]
        assert (top >= placed.vertices[:, 2].max() - 0.03).all() and len(top) >= 6


def test_the_dress_is_made_for_the_body(dresses, avatar):
    straps, strapless = dresses["straps"], dresses["strapless"]
    assert len(boundary_loops(straps.faces)) == 4  # neckline, two armholes, hem
    assert len(boundary_loops(strapless.faces)) == 2
    for dress in (straps, strapless):
        assert len(nonmanifold_edges(dress.faces)) == 0 and dress.meta["kind"] == "dress"
        check_clear_of_body(dress, avatar)  # no vertex inside the body
        assert ((dress.uvs >= 0) & (dress.uvs <= 1)).all()
    # the straps rest on the shoulders, the strapless top band at the chest
    assert straps.vertices[:, 2].max() == pytest.approx(straps.meta["strap_top"], abs=1e-6)
    assert strapless.vertices[strapless.waist, 2] == pytest.approx(chest_height(avatar), abs=1e-5)
    assert straps.meta["strap_top"] > chest_height(avatar) + 0.1 + STRAP_CLEARANCE
    # the paper resolution: about the paper's 9,352 vertices
    big = fit_dress(avatar, DressConfig.preset("paper", "straps"))
    assert 9000 < big.num_vertices < 9800


@pytest.mark.parametrize("unit", ["m", "dm", "cm", "mm", "in"])
def test_every_unit_is_recognised_by_the_garment_s_size(dresses, unit):
    v = dresses["straps"].vertices / UNITS[unit]
    assert detect_units(v)[0] == unit


def test_a_skirt_in_metres_with_z_up_keeps_its_units_and_lands_at_the_waist(avatar, tmp_path):
    from loosefit.fitting.place import fit_skirt
    from loosefit.garment.skirt import SkirtConfig

    skirt = fit_skirt(avatar, SkirtConfig.preset("cpu", "flared"))
    path = _export(skirt, tmp_path / "skirt.obj", "m", "z", shift=(0.0, 0.0, 0.93))
    placed, report = import_garment(path, avatar)
    assert (report["units"]["value"], report["up"]["value"], report["kind"]["value"]) == (
        "m",
        "z",
        "skirt",
    )
    waistband = placed.vertices[placed.waist]
    assert waistband[:, 2].mean() == pytest.approx(natural_waist_height(avatar), abs=2e-3)
    assert np.abs(placed.vertices - skirt.vertices).max() < 0.01  # where fit_skirt puts it
    # --offset moves it after placement
    up, _ = import_garment(path, avatar, offset=(0.0, 0.0, 0.02))
    np.testing.assert_allclose(
        up.vertices - placed.vertices, [[0.0, 0.0, 0.02]] * len(up.vertices), atol=1e-6
    )


def test_a_glb_reads_like_the_obj(dresses, avatar, tmp_path):
    import trimesh

    dress = dresses["straps"]
    x, y, z = dress.vertices.T
    mesh = trimesh.Trimesh(np.stack([x, z, -y], 1), dress.faces, process=False)
    mesh.export(tmp_path / "dress.glb")
    placed, report = import_garment(tmp_path / "dress.glb", avatar)
    assert report["units"]["value"] == "m" and report["up"]["value"] == "y"
    assert report["uv_source"] == "xatlas"  # none in this file: made
    assert np.abs(placed.vertices - dress.vertices).max() < 1e-3


# -- bad files ------------------------------------------------------------------------------


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_an_empty_file_is_refused(tmp_path, avatar):
    with pytest.raises(LoosefitInputError, match=r"empty\.obj.*face.*none"):
        import_garment(_write(tmp_path / "empty.obj", "# nothing\n"), avatar)


def test_nan_is_refused_naming_the_line(tmp_path, avatar):
    path = _write(tmp_path / "nan.obj", "v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n")
    with pytest.raises(LoosefitInputError, match=r"nan\.obj.*line 3.*NaN"):
        import_garment(path, avatar)


def test_several_pieces_are_refused_with_their_sizes(dresses, tmp_path, avatar):
    d = dresses["strapless"]
    v = np.concatenate([d.vertices, d.vertices[:3] + [0, 0, 2.0]])
    f = np.concatenate([d.faces, [[len(d.vertices), len(d.vertices) + 1, len(d.vertices) + 2]]])
    write_obj(tmp_path / "pieces.obj", v, f)
    with pytest.raises(
        LoosefitInputError,
        match=rf"pieces\.obj.*2 disconnected pieces of "
        rf"{d.num_vertices}, 3 vertices",
    ):
        read_garment_mesh(tmp_path / "pieces.obj")


def test_a_non_manifold_edge_is_refused(tmp_path, avatar):
    text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n"
    with pytest.raises(
        LoosefitInputError, match="non-manifold edges, first between vertices 0 and 1"
    ):
        import_garment(_write(tmp_path / "fan.obj", text), avatar)


def test_an_implausible_size_asks_for_the_units(dresses, tmp_path, avatar):
    path = _export(dresses["straps"], tmp_path / "huge.obj", "m", "z")
    v = read_garment_mesh(path).vertices * 1.0e5  # 95 m high in mm, 950 m in cm, ...
    write_obj(path, v.astype(np.float32), dresses["straps"].faces)
    with pytest.raises(LoosefitInputError, match=r"huge\.obj.*units.*--units"):
        import_garment(path, avatar)
    # said explicitly, the unit is the user's to choose
    big, report = import_garment(path, avatar, units="mm")
    assert report["units"] == {"value": "mm", "guessed": False}
    assert np.ptp(big.vertices[:, 2]) == pytest.approx(95.0, rel=0.02)


def test_a_garment_that_cannot_hang_clear_of_the_body_says_where(dresses, tmp_path, avatar):
    path = _export(dresses["strapless"], tmp_path / "low.obj", "cm", "y")
    with pytest.raises(
        LoosefitInputError,
        match=r"low\.obj.*placement.*vertices inside it, the deepest "
        r"\(vertex \d+.*cm in\) at height .* m in the \w+",
    ) as caught:
        import_garment(path, avatar, kind="dress", offset=(0.0, 0.06, -0.1))
    # the fix named first, as a command to run with the options this import was given;
    # the import's own options after it
    hint = caught.value.hint
    command = f"loosefit garment {path} --fit --kind dress --offset=0,0.06,-0.1"
    assert hint.index(command) < hint.index("--units") < hint.index("--offset X,Y,Z"), hint
    assert min(hint.find(o) for o in ("--units", "--kind dress", "--offset")) > hint.find("--fit")
    # deeper than --fit pushes (10 cm): the options come first, --fit's reach after them
    from loosefit.fitting.place import _fit_hint

    deep = _fit_hint(path, import_garment(path, avatar, kind="dress", check=False)[0], avatar, 0.25)
    assert deep.index("--units") < deep.index("--fit") and "no deeper than 10 cm" in deep


def test_a_closed_surface_has_no_up_axis_to_guess(tmp_path, avatar):
    from tests.meshes import cube

    v, f = cube(0.5)
    write_obj(tmp_path / "box.obj", v, f)
    with pytest.raises(LoosefitInputError, match=r"box\.obj.*up.*--up"):
        import_garment(tmp_path / "box.obj", avatar)


def test_bad_options_are_named(dresses, tmp_path, avatar):
    path = _export(dresses["straps"], tmp_path / "d.obj", "cm", "y")
    for kwargs, field in (
        (dict(units="ft"), "--units"),
        (dict(up="x"), "--up"),
        (dict(kind="coat"), "--kind"),
        (dict(attach="none"), "--attach"),
        (dict(attach=np.array([0, 99999])), "--attach"),
    ):
        with pytest.raises(LoosefitInputError, match=field):
            import_garment(path, avatar, **kwargs)


def test_the_garment_command_says_what_it_guessed(dresses, tmp_path, capsys):
    from loosefit.cli import main
    from loosefit.types import GarmentTemplate

    path = _export(dresses["straps"], tmp_path / "mine.obj", "mm", "y")
    assert main(["garment", str(path), "--out", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    assert "units: mm (guessed)" in err and "say --units to change it" in err
    assert "up: y (guessed)" in err and "kind: dress (guessed)" in err
    assert "placed: top over the shoulders" in err
    back = GarmentTemplate.load(tmp_path / "out" / "mine.npz")
    assert np.abs(back.vertices - dresses["straps"].vertices).max() < 1e-3
    # a bad option value: exit 2, a message naming it, nothing written
    assert main(["garment", str(path), "--offset", "1,2", "--out", str(tmp_path / "x")]) == 2
    assert "--offset" in capsys.readouterr().err and not (tmp_path / "x").exists()
    # the parametric ones by name
    assert main(["garment", "dress-strapless", "--out", str(tmp_path / "p")]) == 0
    assert GarmentTemplate.load(tmp_path / "p" / "dress-strapless.npz").meta["kind"] == "dress"


def test_the_attachment_can_be_a_file_of_vertex_indices(dresses, tmp_path, avatar):
    path = _export(dresses["strapless"], tmp_path / "d.obj", "cm", "y")
    (tmp_path / "hold.txt").write_text("0, 1 2\n3")
    placed, report = import_garment(path, avatar, kind="dress", attach=str(tmp_path / "hold.txt"))
    assert placed.waist.tolist() == [0, 1, 2, 3] and report["attachment"]["as"] == "points"
    (tmp_path / "bad.txt").write_text("0 one")
    with pytest.raises(LoosefitInputError, match=r"bad\.txt.*attach.*integers"):
        import_garment(path, avatar, kind="dress", attach=str(tmp_path / "bad.txt"))
    with pytest.raises(LoosefitInputError, match=r"missing\.txt.*attach.*no such file"):
        import_garment(path, avatar, kind="dress", attach=str(tmp_path / "missing.txt"))
