"""The docs hold together: every relative link in README.md, docs/ and bench/ resolves to a
file and, where it names one, a heading (scripts/check_links.py, which a writer runs too);
every dotted ``loosefit.x.y`` name in README.md and the pages under docs/ imports; no page
names a tracker's issue number, and no data file sits among the pages."""

from __future__ import annotations

import importlib
import importlib.util
import re

import pytest

from tests.conftest import REPO


def _checker():
    spec = importlib.util.spec_from_file_location("check_links", REPO / "scripts/check_links.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_relative_link_resolves():
    check = _checker()
    broken = [b for path in check.markdown_files(REPO) for b in check.broken_links(path)]
    assert not broken, "broken links:\n" + "\n".join(broken)


def test_a_broken_link_and_a_missing_heading_are_found(tmp_path):
    check = _checker()
    page = tmp_path / "page.md"
    (tmp_path / "other.md").write_text("# A heading\n")
    page.write_text(
        "[ok](other.md#a-heading) [gone](missing.md) [no](other.md#nowhere)\n`[code](skipped.md)`\n"
        "a link whose [text runs\nonto the next line](also_missing.md)\n"
    )
    broken = check.broken_links(page)
    assert len(broken) == 3 and any("missing.md" in b for b in broken)
    assert any("nowhere" in b for b in broken)
    assert any(b.endswith(":3: also_missing.md (no such file)") for b in broken)


# a dotted name, also one broken after a dot at the end of a line; not a format tag
# (``loosefit.motion/1``)
DOTTED = re.compile(
    r"\bloosefit(?:\.[A-Za-z_]\w*)+(?:\.\n[ \t]*[A-Za-z_]\w*(?:\.[A-Za-z_]\w*)*)?(?![\w/])"
)


def dotted_names(text: str) -> set[str]:
    """Every ``loosefit.x.y.z`` named in ``text`` (a line break after a dot joined)."""
    return {re.sub(r"\s+", "", m.group(0)) for m in DOTTED.finditer(text)}


def resolve(name: str):
    """The object a dotted name names: its longest importable module, then attributes."""
    parts = name.split(".")
    for k in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:k]))
        except ModuleNotFoundError as exc:
            if exc.name not in {".".join(parts[:j]) for j in range(1, k + 1)}:
                raise  # the module exists and fails to import: a real error
            continue
        for attribute in parts[k:]:
            obj = getattr(obj, attribute)
        return obj
    raise ModuleNotFoundError(name)


def pages() -> list:
    """README.md and every page under docs/, however deep."""
    return [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md"))]


def test_every_dotted_loosefit_name_in_the_docs_resolves():
    missing = []
    for page in pages():
        for name in sorted(dotted_names(page.read_text(encoding="utf-8"))):
            try:
                resolve(name)
            except (ImportError, AttributeError) as exc:
                missing.append(f"{page.relative_to(REPO)}: {name} ({exc})")
    assert not missing, "names in the docs that do not resolve:\n" + "\n".join(missing)


def test_dotted_names_are_found_across_lines_and_a_missing_one_fails():
    text = (
        "see `loosefit.motion.\n  bvh.read_bvh`, format `loosefit.motion/1`, and loosefit.nowhere."
    )
    assert dotted_names(text) == {"loosefit.motion.bvh.read_bvh", "loosefit.nowhere"}
    assert callable(resolve("loosefit.motion.bvh.read_bvh"))
    with pytest.raises(AttributeError):
        resolve("loosefit.motion.chain.rollout_timeline")


# "issue 34", "issues 5", "#37" (not an anchor "FILE.md#2026-...", "(#a)", nor a colour
# "#333333"); in prose, also "before-34" and "wave 5" (code may name a file or flag so)
ISSUE = re.compile(r"\bissues?\s+#?\d+\b|(?<![\w.(/#&])#\d{2,4}(?![\w-])", re.IGNORECASE)
ISSUE_IN_PROSE = re.compile(r"\b(?:before|after)[-_]\d+\b|\bwave\s+\d+\b", re.IGNORECASE)


def issue_numbers(text: str, prose: str) -> list[str]:
    """The tracker references in a page's ``text`` (and ``prose``: its text outside code)."""
    return [m.group(0) for m in ISSUE.finditer(text)] + [
        m.group(0) for m in ISSUE_IN_PROSE.finditer(prose)
    ]


def test_no_page_names_an_issue_number():
    check = _checker()
    found = []
    for page in pages():
        prose = "\n".join(line for _, line in check.prose_lines(page))
        for hit in issue_numbers(page.read_text(encoding="utf-8"), prose):
            found.append(f"{page.relative_to(REPO)}: {hit!r}")
    assert not found, "say what the thing is, not its issue number:\n" + "\n".join(found)


def test_issue_numbers_are_found_and_anchors_and_colours_are_not():
    text = "see issue 34, Issues #5 and #37; [a](X.md#2026-11-26-run), [b](#12-frames), #333333"
    assert issue_numbers(text, "before-34 and wave 5") == [
        "issue 34",
        "Issues #5",
        "#37",
        "before-34",
        "wave 5",
    ]
    assert issue_numbers("the 34 clips, 2 waves", "before 3 frames, after 2026-11-26") == []


def test_no_data_file_among_the_pages():
    data = sorted(p.relative_to(REPO) for p in (REPO / "docs").rglob("*.json"))
    assert not data, f"JSON belongs in bench/figures/, not among the pages: {data}"
