"""Check that every relative Markdown link in README.md, docs/ and bench/ resolves.

A link resolves when its file (or folder) exists relative to the Markdown file that holds
it and, where it names an anchor (``FILE.md#a-heading``), a heading of that file has that
anchor (GitHub's rule: lower case, punctuation dropped, spaces to hyphens). Links to web
addresses are not fetched. Links inside fenced code blocks and inline code are skipped; a
link whose text runs onto the next line is checked too. Every page under docs/ and bench/
is read, however deep.

    python scripts/check_links.py            # prints each broken link; exit status 1 if any
"""

from __future__ import annotations

import bisect
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LINK = re.compile(r"!?\[(?:[^\]\[]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
FENCE = re.compile(r"^\s*(```|~~~)")
INLINE_CODE = re.compile(r"`[^`]*`")


def markdown_files(root: Path) -> list[Path]:
    files = [root / "README.md"]
    for folder in ("docs", "bench"):
        files += sorted((root / folder).rglob("*.md"))
    return [f for f in files if f.is_file()]


def prose_lines(path: Path, code: bool = False) -> list[tuple[int, str]]:
    """(line number, text) of the lines outside fenced code, inline code removed unless
    ``code``."""
    lines, fenced = [], False
    for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        if FENCE.match(line):
            fenced = not fenced
            continue
        if not fenced:
            lines.append((number, line if code else INLINE_CODE.sub("", line)))
    return lines


def anchor(heading: str) -> str:
    """GitHub's anchor of a heading's text."""
    text = re.sub(r"[`*_]|<[^>]+>", "", heading.strip()).lower()
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", text)
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(path: Path) -> set[str]:
    found, seen = set(), {}
    for _, line in prose_lines(path, code=True):
        match = re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line)
        if match:
            name = anchor(match.group(1))
            count = seen.get(name, 0)
            seen[name] = count + 1
            found.add(name if count == 0 else f"{name}-{count}")
    return found


def links(path: Path) -> list[tuple[int, str]]:
    """(line number, target) of every link in ``path``'s prose, a link whose text runs onto
    the next line included (numbered by the line it starts on)."""
    lines = prose_lines(path)
    text = "\n".join(line for _, line in lines)
    starts = [0]
    for _, line in lines:
        starts.append(starts[-1] + len(line) + 1)
    found = []
    for match in LINK.finditer(text):
        row = bisect.bisect_right(starts, match.start()) - 1
        found.append((lines[row][0], match.group(1)))
    return found


def broken_links(path: Path) -> list[str]:
    problems = []
    for number, target in links(path):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.IGNORECASE):
            continue  # https:, mailto:, ...
        file_part, _, fragment = target.partition("#")
        resolved = (path.parent / file_part).resolve() if file_part else path
        shown = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
        where = f"{shown}:{number}: {target}"
        if not resolved.exists():
            problems.append(f"{where} (no such file)")
        elif fragment and resolved.suffix == ".md" and fragment not in anchors(resolved):
            problems.append(f"{where} (no heading #{fragment})")
    return problems


def main() -> int:
    files = markdown_files(ROOT)
    problems = [p for f in files for p in broken_links(f)]
    for problem in problems:
        print(problem)
    count = sum(len(links(f)) for f in files)
    print(f"{len(files)} Markdown files, {count} links, {len(problems)} broken")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
