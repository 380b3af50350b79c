import pytest

from loosefit.errors import LoosefitInputError
from loosefit.view.config import COLOURINGS, LAYOUTS, ViewerConfig


def test_the_defaults_are_valid_for_one_sequence():
    config = ViewerConfig()
    config.validate(1)
    assert config.host == "127.0.0.1" and config.layout in LAYOUTS
    assert config.colouring in COLOURINGS


def test_the_edges_of_each_range_are_accepted():
    ViewerConfig(bins=2, speed=4.0, spacing=0.0, port=0, pixel_ratio=0.1, reference=2).validate(3)
    ViewerConfig(bins=64, port=65535, pixel_ratio=4.0, colouring="error").validate(2)
    ViewerConfig(layout="overlaid", colouring="inside").validate(1)


@pytest.mark.parametrize(
    ("change", "sequences", "field", "found"),
    [
        ({"layout": "grid"}, 1, "layout", "'grid'"),
        ({"colouring": "speed"}, 1, "colouring", "'speed'"),
        ({"colouring": "error"}, 1, "colouring", "'one sequence'"),
        ({"reference": 2}, 2, "reference", "2"),
        ({"reference": -1}, 2, "reference", "-1"),
        ({"bins": 1}, 1, "bins", "1"),
        ({"bins": 65}, 1, "bins", "65"),
        ({"speed": 0.0}, 1, "speed", "0.0"),
        ({"speed": 4.5}, 1, "speed", "4.5"),
        ({"spacing": -0.1}, 1, "spacing", "-0.1"),
        ({"port": 65536}, 1, "port", "65536"),
        ({"pixel_ratio": 0.05}, 1, "pixel_ratio", "0.05"),
    ],
)
def test_each_field_out_of_range_is_refused_by_name(change, sequences, field, found):
    with pytest.raises(LoosefitInputError) as err:
        ViewerConfig(**change).validate(sequences)
    assert (err.value.source, err.value.field, err.value.found) == ("viewer", field, found)


def test_the_reference_range_names_the_sequences():
    with pytest.raises(LoosefitInputError, match=r"expected 0 to 2 \(one of the 3 sequences\)"):
        ViewerConfig(reference=3).validate(3)
