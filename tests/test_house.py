"""The house rules: no module of src/loosefit over 800 lines, no function over 120.

A function's length is ``end_lineno - lineno + 1`` from :mod:`ast` (its docstring
included); a module's is its number of lines.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "loosefit"
MAX_MODULE_LINES = 800
MAX_FUNCTION_LINES = 120


def too_long(text: str, where: str) -> list[str]:
    """What in one module's ``text`` breaks the rules, as ``where:line name, length``."""
    out = []
    lines = len(text.splitlines())
    if lines > MAX_MODULE_LINES:
        out.append(f"{where}: the module, {lines} lines (at most {MAX_MODULE_LINES})")
    for node in ast.walk(ast.parse(text, filename=where)):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            length = node.end_lineno - node.lineno + 1
            if length > MAX_FUNCTION_LINES:
                out.append(
                    f"{where}:{node.lineno} {node.name}, {length} lines "
                    f"(at most {MAX_FUNCTION_LINES})"
                )
    return out


def test_no_module_or_function_too_long() -> None:
    modules = sorted(PACKAGE.rglob("*.py"))
    assert len(modules) > 10, f"no package at {PACKAGE}"
    broken = [
        msg
        for path in modules
        for msg in too_long(
            path.read_text(encoding="utf-8"), path.relative_to(PACKAGE.parents[1]).as_posix()
        )
    ]
    assert not broken, "split these:\n" + "\n".join(broken)


def test_the_check_names_what_is_too_long() -> None:
    body = "".join(f"    x{i} = {i}\n" for i in range(MAX_FUNCTION_LINES))
    fits = f"def fits():\n{body[: body.rindex('    x')]}"
    assert too_long(fits, "m.py") == []
    long = f"\n\ndef long_one():\n{body}"
    assert too_long(long, "m.py") == [
        f"m.py:3 long_one, {MAX_FUNCTION_LINES + 1} lines (at most 120)"
    ]
    big = "x = 0\n" * (MAX_MODULE_LINES + 1)
    assert too_long(big, "big.py") == [
        f"big.py: the module, {MAX_MODULE_LINES + 1} lines (at most 800)"
    ]
