"""Rollout reports: every Markdown row has as many cells as the header names."""

from __future__ import annotations

import pytest

from loosefit.eval.report import rollout_markdown


def _result(horizons: dict, surface: bool) -> dict:
    clip = {"frames": 16, "rmse_cm": 1.5, "horizons": horizons, "frames_per_second": 30.0}
    if surface:
        clip |= {"hausdorff_cm": 4.0, "sted": 0.25}
    return {"split": "test", "clips": {"c": clip}, **clip}


@pytest.mark.parametrize("horizons", [{}, {100: 1.2}, {100: 1.2, 500: 1.4}])
@pytest.mark.parametrize("surface", [False, True])
def test_rows_match_the_header(horizons, surface):
    table = [
        ln for ln in rollout_markdown(_result(horizons, surface)).splitlines() if ln[:1] == "|"
    ]
    head, rule, *rows = table
    width = head.count("|")
    assert rule.count("|") == width and all(r.count("|") == width for r in rows)
    names = [c.strip() for c in head.strip("|").split("|")]
    assert "" not in names  # no unnamed column (a clip shorter than every horizon)
    assert names[-1] == "rollout fps" and ("STED" in names) == surface
    assert [f"iter-{h}" for h in horizons] == [n for n in names if n.startswith("iter-")]
    cells = [c.strip() for c in rows[0].strip("|").split("|")]
    assert cells[:3] == ["c", "16", "1.500"] and cells[-1] == "30"


def test_a_section_is_put_in_place_of_its_own_or_after_the_first():
    from loosefit.eval.report import splice_section

    page = "# T\n\n## A\na\n\n## B\nold\n\n## C\nc\n"
    new = splice_section(page, "## B", "## B\nnew\n")
    assert new == "# T\n\n## A\na\n\n## B\nnew\n\n## C\nc\n"
    added = splice_section("# T\n\n## A\na\n\n## C\nc\n", "## B", "## B\nb")
    assert added == "# T\n\n## A\na\n\n## B\nb\n\n## C\nc\n"
    assert splice_section(added, "## B", "## B\nb") == added  # again: the same page


def test_a_page_becomes_a_section_one_level_down():
    from loosefit.eval.report import as_section

    page = (
        "# Where it goes\n\nintro\n\n## Clip a\n\n```\n# a comment\n## not a heading\n```\n#tag\n"
    )
    assert as_section(page, "## Profile") == (
        "## Profile\n\nintro\n\n### Clip a\n\n```\n# a comment\n## not a heading\n```\n#tag\n"
    )
    assert as_section("no title\n", "## S") == "## S\nno title\n"


def test_a_section_written_into_a_page_keeps_the_rest(tmp_path):
    from loosefit.eval.report import write_section

    path = tmp_path / "SPEED.md"
    write_section(path, "## B", "# Bee\n\nfirst\n")
    assert path.read_text() == "## B\n\nfirst\n"
    path.write_text("# Speed\n\n## A\na\n\n## B\nold\n\n## C\nc\n")
    write_section(path, "## B", "# Bee\n\nnew\n\n## Part\nx\n")
    assert path.read_text() == "# Speed\n\n## A\na\n\n## B\n\nnew\n\n### Part\nx\n\n## C\nc\n"
