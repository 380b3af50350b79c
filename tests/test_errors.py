"""LoosefitInputError: the message names the source, the field, what was expected and found,
and the error crosses a process boundary whole."""

from __future__ import annotations

import pickle
from pathlib import Path

import pytest

from loosefit.errors import LoosefitInputError


def test_the_message_names_file_field_expected_and_found():
    err = LoosefitInputError(Path("61_01.bvh"), "MOTION/Frames", "2242 frame lines", "2241")
    assert str(err) == "61_01.bvh: field 'MOTION/Frames': expected 2242 frame lines, found 2241"
    assert (err.source, err.field, err.expected, err.found) == (
        "61_01.bvh",
        "MOTION/Frames",
        "2242 frame lines",
        "2241",
    )
    assert isinstance(err, ValueError)  # callers that catch ValueError still catch it


def test_a_hint_follows_in_brackets_and_no_source_reads_as_input():
    err = LoosefitInputError(None, "fps", "a positive number", "-3", hint="try --fps 30")
    assert str(err) == "<input>: field 'fps': expected a positive number, found -3 (try --fps 30)"
    assert err.hint == "try --fps 30"


def test_it_arrives_whole_from_another_process():
    err = LoosefitInputError("a.obj", "faces", "triangles", "a pentagon", hint="triangulate")
    back = pickle.loads(pickle.dumps(err))
    assert type(back) is LoosefitInputError and str(back) == str(err)
    assert (back.source, back.field, back.expected, back.found, back.hint) == (
        "a.obj",
        "faces",
        "triangles",
        "a pentagon",
        "triangulate",
    )
    with pytest.raises(LoosefitInputError, match="found a pentagon"):
        raise back
