"""Reading a garment's frame from its shape: the up axis from its openings, the unit from its
size, the top opening, the kind; on a tube whose every answer is known."""

from __future__ import annotations

import numpy as np
import pytest

from loosefit.errors import LoosefitInputError
from loosefit.garment.importer import (
    component_sizes,
    detect_kind,
    detect_units,
    detect_up,
    to_z_up,
    top_opening,
)
from tests.meshes import cube


def skirt_tube(n: int = 16, waist: float = 0.18, hem: float = 0.4, height: float = 0.6):
    """A truncated cone, Z up: the waist ring (radius ``waist``) at ``height`` above the wider
    hem ring at 0; vertices (2n, 3) (waist first), faces (2n, 3)."""
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = np.stack([np.cos(a), np.sin(a)], 1)
    v = np.concatenate([np.c_[waist * ring, np.full(n, height)], np.c_[hem * ring, np.zeros(n)]])
    i = np.arange(n)
    j = (i + 1) % n
    f = np.concatenate([np.stack([i, i + n, j], 1), np.stack([j, i + n, j + n], 1)])
    return v, f


def test_every_up_axis_turns_into_z_up():
    p = np.array([[1.0, 2.0, 3.0]])
    assert to_z_up(p, "z").tolist() == [[1, 2, 3]]
    assert to_z_up(p, "y").tolist() == [[1, -3, 2]]  # a Y-up file's front (+Z) faces -Y
    assert to_z_up(p, "-z").tolist() == [[1, -2, -3]]
    assert to_z_up(p, "-y").tolist() == [[1, 3, -2]]
    for up in ("y", "-z", "-y"):  # proper rotations: lengths and handedness kept
        m = to_z_up(np.eye(3), up)
        assert np.linalg.det(m) == pytest.approx(1.0)
    with pytest.raises(LoosefitInputError, match=r"--up: field 'up': expected one of .*found 'x'"):
        to_z_up(p, "x")


@pytest.mark.parametrize("up", ["z", "y", "-z", "-y"])
def test_the_up_axis_is_read_from_the_openings(up):
    v, f = skirt_tube()
    # the file as written with ``up`` its up axis: the inverse of to_z_up
    inverse = {
        "z": lambda x, y, z: (x, y, z),
        "y": lambda x, y, z: (x, z, -y),
        "-z": lambda x, y, z: (x, -y, -z),
        "-y": lambda x, y, z: (x, -z, y),
    }[up]
    written = np.stack(inverse(*v.T), 1)
    np.testing.assert_allclose(to_z_up(written, up), v, atol=1e-12)
    assert detect_up(written, f) == up


def test_one_opening_tells_no_up_axis():
    v, f = skirt_tube()
    n = len(v) // 2
    hem_closed = np.concatenate([v, [[0, 0, 0]]])
    fan = np.stack([np.full(n, 2 * n), (np.arange(n) + 1) % n + n, np.arange(n) + n], 1)
    with pytest.raises(LoosefitInputError, match=r"skirt\.obj: field 'up'.*found 1 opening"):
        detect_up(hem_closed, np.concatenate([f, fan]), "skirt.obj")


def test_the_unit_is_the_one_that_makes_a_garment_of_a_person_s_size():
    v, _ = skirt_tube()  # 0.6 m high, 0.8 m wide
    assert detect_units(v)[0] == "m"
    unit, sizes = detect_units(v * 100)
    assert unit == "cm" and sizes["cm"] == pytest.approx((0.6, 0.8))
    assert detect_units(v / 0.0254)[0] == "in"
    with pytest.raises(LoosefitInputError, match=r"field 'units'.*--units"):
        detect_units(v * 1e5, "huge.obj")


def test_the_top_opening_the_kind_and_the_pieces():
    v, f = skirt_tube(n=12)
    assert sorted(top_opening(v, f).tolist()) == list(range(12))  # the waist ring
    assert top_opening(*cube()) is None
    assert detect_kind(f) == "skirt"
    # more than two openings (here a second tube beside it: four): a dress
    assert detect_kind(np.concatenate([f, f + len(v)])) == "dress"
    cv, cf = cube()
    both = np.concatenate([f, cf + len(v)])
    assert component_sizes(both, len(v) + len(cv)) == [24, 8]
