"""The docs hold together: every relative link in README.md, docs/ and bench/ resolves to a
file and, where it names one, a heading (scripts/check_links.py, which a writer runs too)."""

from __future__ import annotations

import importlib.util

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
    page.write_text("[ok](other.md#a-heading) [gone](missing.md) [no](other.md#nowhere)\n"
                    "`[code](skipped.md)`\n")  # fmt: skip
    broken = check.broken_links(page)
    assert len(broken) == 2 and any("missing.md" in b for b in broken)
    assert any("nowhere" in b for b in broken)
